"""Seeded sensor noise: the Gaussian draws of one reading, a function of the sensor's seed,
its name and the reading's stamp only, so a replay that starts at a keyframe draws the same
numbers as the live run did.

A reading's draws come from numpy's PCG64 seeded by a ``SeedSequence`` of the entropy
``[seed, crc32(name), stamp mod 2**64]``, through a ``Generator``'s ``standard_normal``.
Building those three objects took about 80 us a reading on the robot scene's node (its
IMU reads 50 times a second), so :class:`Noise` computes the state they give in plain
integers instead: the sequence's hash mixing of the entropy's 32-bit words into its pool
of four, the eight words it then generates (two 128-bit numbers, the initial state and the
stream), and PCG64's seeding from them (``pcg_setseq_128_srandom_r``: two steps of the
128-bit LCG). numpy documents both algorithms as stable across versions, and the state is
set on one generator kept per sensor; the draws are the same bits as the three objects'
(``test/sensors/test_noise.py`` holds them to numpy's own).
"""
from __future__ import annotations

import zlib

import numpy as np

__all__ = ["Noise", "pcg64_state"]

_MASK32 = 0xFFFFFFFF
_MASK128 = (1 << 128) - 1
# numpy's SeedSequence (bit_generator.pyx): its hash constants and mixing multipliers.
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = 0xCA01F9DD, 0x4973F715
_POOL_SIZE = 4
#: PCG64's 128-bit LCG multiplier (PCG_DEFAULT_MULTIPLIER_128).
_PCG_MULTIPLIER = 0x2360ED051FC65DA44385DF649FCCF645
#: The most entropy words: a seed below 2**64 (two words), the name's CRC (one), the
#: stamp (two).
_MOST_WORDS = 5


def _hash_constants(init: int, mult: int, count: int) -> tuple[tuple[int, int], ...]:
    """The (xor, multiplier) pair each successive hash of a sequence uses: the constant
    before and after it is multiplied by ``mult``. They do not depend on the data."""
    pairs = []
    constant = init
    for _ in range(count):
        following = constant * mult & _MASK32
        pairs.append((constant, following))
        constant = following
    return tuple(pairs)


#: The entropy hashes: one a pool word, 12 for mixing the pool into itself, 4 for each
#: entropy word beyond the pool's size.
_ENTROPY_HASHES = _hash_constants(
    _INIT_A, _MULT_A, _POOL_SIZE + _POOL_SIZE * (_POOL_SIZE - 1)
    + _POOL_SIZE * (_MOST_WORDS - _POOL_SIZE))
#: The state hashes: one a generated word (four 64-bit words are eight 32-bit ones).
_STATE_HASHES = _hash_constants(_INIT_B, _MULT_B, 8)
#: The pool's (source, destination) pairs as the mixing visits them.
_CROSS = tuple((source, destination) for source in range(_POOL_SIZE)
               for destination in range(_POOL_SIZE) if source != destination)


def _words(value: int) -> list[int]:
    """A non-negative integer's 32-bit words, least significant first (zero is one
    word), as SeedSequence splits an entropy integer."""
    if value == 0:
        return [0]
    words = []
    while value:
        words.append(value & _MASK32)
        value >>= 32
    return words


def pcg64_state(entropy: list[int]) -> tuple[int, int]:
    """The PCG64 ``(state, increment)`` that ``PCG64(SeedSequence(words))`` starts from,
    for the 32-bit ``entropy`` words (at most :data:`_MOST_WORDS`) the sequence assembles
    from its entropy integers (:func:`_words` of each, in order).

    Each hash of a word x is ``x ^= xor; x *= multiplier; x ^= x >> 16`` (32-bit), each
    mix of a hashed y into a pool word x is ``x = L x - R y; x ^= x >> 16``; written out
    inline, as function calls would cost more than the arithmetic."""
    hashes = iter(_ENTROPY_HASHES)
    pool = []
    for i in range(_POOL_SIZE):
        xor, multiplier = next(hashes)
        x = ((entropy[i] if i < len(entropy) else 0) ^ xor) * multiplier & _MASK32
        pool.append(x ^ x >> 16)
    for source, destination in _CROSS:
        xor, multiplier = next(hashes)
        y = (pool[source] ^ xor) * multiplier & _MASK32
        x = (_MIX_MULT_L * pool[destination] - _MIX_MULT_R * (y ^ y >> 16)) & _MASK32
        pool[destination] = x ^ x >> 16
    for word in entropy[_POOL_SIZE:]:
        for destination in range(_POOL_SIZE):
            xor, multiplier = next(hashes)
            y = (word ^ xor) * multiplier & _MASK32
            x = (_MIX_MULT_L * pool[destination] - _MIX_MULT_R * (y ^ y >> 16)) & _MASK32
            pool[destination] = x ^ x >> 16
    w = []
    for i, (xor, multiplier) in enumerate(_STATE_HASHES):
        x = (pool[i % _POOL_SIZE] ^ xor) * multiplier & _MASK32
        w.append(x ^ x >> 16)
    # Four uint64 (pairs of words, low first): the initial state's high and low halves,
    # then the stream's.
    initial = w[1] << 96 | w[0] << 64 | w[3] << 32 | w[2]
    increment = ((w[5] << 96 | w[4] << 64 | w[7] << 32 | w[6]) << 1 | 1) & _MASK128
    # From state 0: a step (state * multiplier + increment), the initial state added,
    # another step.
    return ((increment + initial) * _PCG_MULTIPLIER + increment) & _MASK128, increment


class Noise:
    """The noise of one sensor: :meth:`normals` of a reading are the standard normal
    draws of ``np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed,
    zlib.crc32(name.encode()), stamp_ns % 2**64])))``."""

    def __init__(self, seed: int, name: str) -> None:
        if seed < 0:
            raise ValueError(f"a noise seed is a non-negative integer, not {seed}")
        self._prefix = _words(seed) + _words(zlib.crc32(name.encode()))
        self._bits = np.random.PCG64(0)
        self._generator = np.random.Generator(self._bits)

    def normals(self, stamp_ns: int, count: int) -> np.ndarray:
        """The ``count`` standard normal draws of the reading stamped ``stamp_ns``."""
        state, increment = pcg64_state(self._prefix + _words(stamp_ns % (1 << 64)))
        self._bits.state = {"bit_generator": "PCG64",
                            "state": {"state": state, "inc": increment},
                            "has_uint32": 0, "uinteger": 0}
        return self._generator.standard_normal(count)
