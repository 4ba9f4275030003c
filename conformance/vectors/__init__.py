"""The frozen MPZ conformance vectors (data only; see manifest.json and ../README.md).

Installed as the data package ``mpz.conformance.vectors`` so that ``mpz-conformance``
finds them in a checkout and in a wheel alike. Regenerate only with
``python -m mpz.tools.make_vectors``.
"""
