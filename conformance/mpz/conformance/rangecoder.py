"""Spec §5 range encoder, transcribed line by line from the text (slow, obviously correct).

An executable reading of §5.1-§5.6 for implementers and for the project's own checks:
``tests/test_entropy.py`` holds :mod:`mpz.entropy` to it byte for byte, and
``bench/bench_entropy.py`` runs it as the same-process baseline. It shares no code
with :mod:`mpz.entropy`.
"""
from __future__ import annotations


class RefEncoder:
    """Spec §5.1-§5.6 written out independently (slow, obviously correct)."""

    def __init__(self):
        self.low, self.range, self.cache, self.csize, self.out = 0, 0xFFFFFFFF, 0, 1, bytearray()

    def shift_low(self):
        if self.low < 0xFF000000 or self.low >= 1 << 32:
            carry = self.low >> 32
            temp = self.cache
            while True:
                self.out.append((temp + carry) & 0xFF)
                temp = 0xFF
                self.csize -= 1
                if self.csize == 0:
                    break
            self.cache = (self.low >> 24) & 0xFF
        self.csize += 1
        self.low = (self.low & 0x00FFFFFF) << 8

    def bit(self, probs, key, b):
        p = probs.get(key, 1024)
        bound = (self.range >> 11) * p
        if b == 0:
            self.range = bound
            probs[key] = p + ((2048 - p) >> 5)
        else:
            self.low += bound
            self.range -= bound
            probs[key] = p - (p >> 5)
        while self.range < 1 << 24:
            self.range = (self.range << 8) & 0xFFFFFFFF
            self.shift_low()

    def integer(self, probs, a, c, v, signed):
        if v == 0:
            self.bit(probs, ("Z", a, c), 0)
            return
        self.bit(probs, ("Z", a, c), 1)
        u = abs(v)
        if signed:
            self.bit(probs, ("S", a, c), 1 if v < 0 else 0)
        k = u.bit_length() - 1
        for i in range(k):
            self.bit(probs, ("E", a, c, i), 1)
        if k < 30:
            self.bit(probs, ("E", a, c, k), 0)
        for j in range(k):
            self.bit(probs, ("X", a, k, j), (u >> (k - 1 - j)) & 1)

    def block(self, v, period=None, signed=True):
        T, M, A = v.shape
        period = period or T
        probs: dict[tuple[int, ...], int] = {}
        for t in range(T):
            for m in range(M):
                for a in range(A):
                    cv = 0
                    if t % period:
                        cv += 2 * abs(int(v[t - 1, m, a]))
                    if m:
                        cv += abs(int(v[t, m - 1, a]))
                    self.integer(probs, a, min(7, cv.bit_length()), int(v[t, m, a]), signed)

    def finish(self):
        for _ in range(5):
            self.shift_low()
        return bytes(self.out)
