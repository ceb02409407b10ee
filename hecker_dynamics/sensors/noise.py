"""Seeded sensor noise: the Gaussian draws of one reading, a function of the sensor's seed,
its name and the reading's stamp only, so a replay that starts at a keyframe draws the same
numbers as the live run did.

A reading's draws come from numpy's PCG64 seeded by a ``SeedSequence`` of the entropy
``[seed, crc32(name), stamp mod 2**64]``, through a ``Generator``'s ``standard_normal``.
Building those three objects took 70 to 110 us a reading in the robot scene's node (its
IMU reads 50 times a second), and the sequence's hashing in plain Python integers still
25 us. :class:`Noise` computes the states those objects start from for the readings ahead
at once, in numpy's 32-bit integer arrays, one lane a reading: the sequence's hash mixing
of the entropy's 32-bit words into its pool of four, the eight words it then generates
(two 128-bit numbers, the initial state and the stream), and, as each reading comes,
PCG64's seeding from them (``pcg_setseq_128_srandom_r``: two steps of the 128-bit LCG),
set on one generator kept per sensor. numpy documents both algorithms as stable across
versions; the draws are the same bits as the three objects' (``test/sensors/
test_noise.py`` holds them to numpy's own). A reading of a few draws (an IMU's four) has
them drawn with its batch's seeds, every reading's in one pass: set reading by reading,
the generator's state and its draws made the IMU's reading cost about 60 us after each of
the node's 20 ms sleeps, which leave the caches cold, and about 22 us drawn ahead.
"""
from __future__ import annotations

import zlib

import numpy as np

__all__ = ["Noise", "BATCH", "DRAWN_AHEAD"]

_MASK32 = 0xFFFFFFFF
_MASK128 = (1 << 128) - 1
# numpy's SeedSequence (bit_generator.pyx): its hash constants and mixing multipliers.
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = np.uint32(0xCA01F9DD), np.uint32(0x4973F715)
_POOL_SIZE = 4
#: PCG64's 128-bit LCG multiplier (PCG_DEFAULT_MULTIPLIER_128).
_PCG_MULTIPLIER = 0x2360ED051FC65DA44385DF649FCCF645
#: The most entropy words: a seed below 2**64 (two words), the name's CRC (one), the
#: stamp (two).
_MOST_WORDS = 5
#: Readings whose states are computed together: the stamps one sensor period apart from
#: the one asked for.
BATCH = 256
#: The most draws a reading may have for a batch's readings to be drawn with their seeds
#: (:meth:`Noise.normals`); a laser's hundreds of draws a scan are drawn as it comes.
DRAWN_AHEAD = 8


def _hash_constants(init: int, mult: int, count: int) -> list[tuple[np.uint32, np.uint32]]:
    """The (xor, multiplier) pair each successive hash of a sequence uses: the constant
    before and after it is multiplied by ``mult``. They do not depend on the data."""
    pairs = []
    constant = init
    for _ in range(count):
        following = constant * mult & _MASK32
        pairs.append((np.uint32(constant), np.uint32(following)))
        constant = following
    return pairs


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
_SHIFT = np.uint32(16)


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


def _hashed(x: np.ndarray, constants: tuple[np.uint32, np.uint32]) -> np.ndarray:
    """SeedSequence's hash of 32-bit words: xor, multiply (mod 2**32), xorshift."""
    xor, multiplier = constants
    x = (x ^ xor) * multiplier
    return x ^ (x >> _SHIFT)


def _mixed(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """SeedSequence's mix of a hashed word ``y`` into a pool word ``x``."""
    mixed: np.ndarray = _MIX_MULT_L * x - _MIX_MULT_R * y
    return mixed ^ (mixed >> _SHIFT)


def seed_words(entropy: list[np.ndarray]) -> list[np.ndarray]:
    """The four uint64 words that ``SeedSequence(...).generate_state(4, np.uint64)``
    gives, lane by lane, for entropy given as its 32-bit words (at most
    :data:`_MOST_WORDS`), each a uint32 array of one word per lane."""
    hashes = iter(_ENTROPY_HASHES)
    lanes = entropy[0].shape
    pool = [_hashed(entropy[i] if i < len(entropy) else np.zeros(lanes, np.uint32),
                    next(hashes)) for i in range(_POOL_SIZE)]
    for source, destination in _CROSS:
        pool[destination] = _mixed(pool[destination], _hashed(pool[source], next(hashes)))
    for word in entropy[_POOL_SIZE:]:
        for destination in range(_POOL_SIZE):
            pool[destination] = _mixed(pool[destination], _hashed(word, next(hashes)))
    state = [_hashed(pool[i % _POOL_SIZE], constants).astype(np.uint64)
             for i, constants in enumerate(_STATE_HASHES)]
    return [state[i] | state[i + 1] << np.uint64(32) for i in range(0, 8, 2)]


def pcg64_state(words: tuple[int, int, int, int]) -> tuple[int, int]:
    """PCG64's ``(state, increment)`` after its seeding from the four uint64 ``words``
    (the initial state's high and low halves, then the stream's): from state 0, a step
    (state * multiplier + increment), the initial state added, another step."""
    initial = words[0] << 64 | words[1]
    increment = ((words[2] << 64 | words[3]) << 1 | 1) & _MASK128
    return ((increment + initial) * _PCG_MULTIPLIER + increment) & _MASK128, increment


class Noise:
    """The noise of one sensor whose readings are ``period_ns`` apart: :meth:`normals`
    of a reading are the standard normal draws of ``np.random.Generator(np.random.PCG64(
    np.random.SeedSequence([seed, zlib.crc32(name.encode()), stamp_ns % 2**64])))``.

    The seeds of :data:`BATCH` readings are computed at once: the one asked for and
    those after it a period apart (as many as split into as many 32-bit words)."""

    def __init__(self, seed: int, name: str, period_ns: int) -> None:
        if seed < 0:
            raise ValueError(f"a noise seed is a non-negative integer, not {seed}")
        if period_ns <= 0:
            raise ValueError(f"a sensor's period is positive, not {period_ns} ns")
        self.period_ns = period_ns
        self._prefix = _words(seed) + _words(zlib.crc32(name.encode()))
        #: The seed words of the readings ahead, by stamp (mod 2**64).
        self._ahead: dict[int, tuple[int, int, int, int]] = {}
        self._bits = np.random.PCG64(0)
        self._generator = np.random.Generator(self._bits)
        #: The draws of the readings ahead, by stamp (mod 2**64), and how many a reading.
        self._drawn: dict[int, np.ndarray] = {}
        self._drawn_count = 0

    def _batch(self, stamp: int) -> dict[int, tuple[int, int, int, int]]:
        """The seed words of the readings at ``stamp`` (mod 2**64) and after it."""
        size = len(_words(stamp))
        stamps = [s % (1 << 64) for s in range(stamp, stamp + BATCH * self.period_ns,
                                                  self.period_ns)]
        stamps = stamps[:next((k for k, s in enumerate(stamps) if len(_words(s)) != size),
                              len(stamps))]
        values = np.array(stamps, dtype=np.uint64)
        entropy = [np.full(len(stamps), word, np.uint32) for word in self._prefix]
        entropy += [(values >> np.uint64(32 * k) & np.uint64(_MASK32)).astype(np.uint32)
                    for k in range(size)]
        columns = [column.tolist() for column in seed_words(entropy)]
        return {s: words for s, words in zip(stamps, zip(*columns))}

    def normals(self, stamp_ns: int, count: int) -> np.ndarray:
        """The ``count`` standard normal draws of the reading stamped ``stamp_ns``; up to
        :data:`DRAWN_AHEAD` of them, drawn with the batch's (the same bits)."""
        stamp = stamp_ns % (1 << 64)
        if count <= DRAWN_AHEAD:
            drawn = self._drawn.pop(stamp, None) if count == self._drawn_count else None
            if drawn is None:
                self._drawn_count = count
                self._drawn = {ahead: self._draw(words, count)
                               for ahead, words in self._batch(stamp).items()}
                drawn = self._drawn.pop(stamp)
            return drawn
        words = self._ahead.pop(stamp, None)
        if words is None:
            self._ahead = self._batch(stamp)
            words = self._ahead.pop(stamp)
        return self._draw(words, count)

    def _draw(self, words: tuple[int, int, int, int], count: int) -> np.ndarray:
        """``count`` draws of the generator PCG64 seeds from ``words``."""
        state, increment = pcg64_state(words)
        self._bits.state = {"bit_generator": "PCG64",
                            "state": {"state": state, "inc": increment},
                            "has_uint32": 0, "uinteger": 0}
        return self._generator.standard_normal(count)
