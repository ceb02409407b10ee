"""Sensor noise: the draws of :class:`Noise` are numpy's own from a SeedSequence of (seed,
crc32(name), stamp), bit for bit, whatever the entropy's number of 32-bit words and
wherever a sensor's readings fall."""
from __future__ import annotations

import zlib

import numpy as np
import pytest

from hecker_dynamics.sensors.noise import BATCH, DRAWN_AHEAD, Noise, seed_words

# Seeds of one and two words (the largest a scene takes is 2**63), stamps of one and two
# words, zero (one word), and past 2**64 (taken modulo 2**64): entropies of 3 to 5 words,
# the last beyond SeedSequence's pool of four.
SEEDS = [0, 1, 2, 2**32 - 1, 2**32, 2**40 + 5, 2**63]
STAMPS = [0, 1, 2**32 - 1, 2**32, 20_000_000, 1_765_000_000_123_456_789, 2**64 - 1, 2**64 + 3]
NAMES = ["robot/imu", "robot/laser", ""]
PERIOD = 20_000_000


def numpy_generator(seed: int, name: str, stamp_ns: int) -> np.random.Generator:
    """The definition of a reading's generator (docs/scenes.md): numpy's objects."""
    entropy = [seed, zlib.crc32(name.encode()), stamp_ns % (1 << 64)]
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy)))


def assert_draws(noise: Noise, seed: int, name: str, stamp: int, count: int = 181) -> None:
    expected = numpy_generator(seed, name, stamp).standard_normal(count)
    assert noise.normals(stamp, count).tobytes() == expected.tobytes(), (seed, name, stamp)


@pytest.mark.parametrize("seed", SEEDS)
def test_draws_are_numpy_seed_sequence_bits(seed: int) -> None:
    for name in NAMES:
        noise = Noise(seed, name, PERIOD)
        for stamp in STAMPS:
            assert_draws(noise, seed, name, stamp)


def test_seed_words_are_the_sequence_state() -> None:
    """Lane by lane, whatever the entropy's length (3 to 5 words)."""
    entropies = [[seed, zlib.crc32(name.encode()), stamp % (1 << 64)]
                 for seed in SEEDS for name in NAMES for stamp in STAMPS]
    for length in (3, 4, 5):
        lanes = [e for e in entropies if sum(len(_words(value)) for value in e) == length]
        words = [np.array([w for value in e for w in _words(value)], dtype=np.uint32)
                 for e in lanes]
        ours = seed_words([np.array([w[k] for w in words], dtype=np.uint32)
                           for k in range(length)])
        for lane, entropy in enumerate(lanes):
            expected = np.random.SeedSequence(entropy).generate_state(4, np.uint64).tolist()
            assert [int(column[lane]) for column in ours] == expected, entropy


def _words(value: int) -> list[int]:
    return [0] if value == 0 else [(value >> (32 * k)) & 0xFFFFFFFF
                                   for k in range((value.bit_length() + 31) // 32)]


@pytest.mark.parametrize("start", [0, 2**32 - 3 * PERIOD, 2**64 - 5 * PERIOD,
                                   1_765_000_000_123_456_789])
def test_a_sensors_readings_across_batches_and_word_counts(start: int) -> None:
    """Readings a period apart, more than a batch of them, across the stamps where the
    stamp's words grow from one to two and where they wrap past 2**64."""
    noise = Noise(3, "robot/imu", PERIOD)
    for k in range(BATCH + 10):
        assert_draws(noise, 3, "robot/imu", start + k * PERIOD, 4)


def test_readings_do_not_depend_on_earlier_ones() -> None:
    """A reading's draws are the same whatever was drawn before and in whatever order
    the stamps come (a replay that starts at a keyframe, a sampling off the period)."""
    noise = Noise(7, "robot/imu", PERIOD)
    first = noise.normals(40_000_000, 4)
    for stamp in (60_000_000, 45_000_000, 20_000_000, 40_000_000, 40_000_000):
        assert_draws(noise, 7, "robot/imu", stamp, 4)
    assert Noise(7, "robot/imu", PERIOD).normals(40_000_000, 4).tobytes() == first.tobytes()


def test_bad_seed_and_period_are_refused() -> None:
    with pytest.raises(ValueError, match="non-negative"):
        Noise(-1, "robot/imu", PERIOD)
    with pytest.raises(ValueError, match="positive"):
        Noise(1, "robot/imu", 0)


def test_readings_of_few_and_many_draws_on_one_sensor() -> None:
    """An IMU's few draws come with their batch's seeds, a laser's hundreds as each reading
    comes: switching between the two, and between two small counts, still draws each
    reading's own numbers, ahead of and behind the batch."""
    noise = Noise(5, "robot/imu", PERIOD)
    counts = [4, 4, DRAWN_AHEAD, 181, 4, 3, 1, DRAWN_AHEAD + 1, 4]
    for k, count in enumerate(counts):
        assert_draws(noise, 5, "robot/imu", (7 - 3 * k) % 11 * PERIOD, count)
