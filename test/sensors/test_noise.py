"""Sensor noise: the draws of :class:`Noise` are numpy's own from a SeedSequence of (seed,
crc32(name), stamp), bit for bit, whatever the entropy's number of 32-bit words."""
from __future__ import annotations

import zlib

import numpy as np
import pytest

from hecker_dynamics.sensors.noise import Noise, pcg64_state

# Seeds of one and two words (the largest a scene takes is 2**63), stamps of one and two
# words, zero (one word), and past 2**64 (taken modulo 2**64): entropies of 3 to 5 words,
# the last beyond SeedSequence's pool of four.
SEEDS = [0, 1, 2, 2**32 - 1, 2**32, 2**40 + 5, 2**63]
STAMPS = [0, 1, 2**32 - 1, 2**32, 20_000_000, 1_765_000_000_123_456_789, 2**64 - 1, 2**64 + 3]
NAMES = ["robot/imu", "robot/laser", ""]


def numpy_generator(seed: int, name: str, stamp_ns: int) -> np.random.Generator:
    """The definition of a reading's generator (docs/scenes.md): numpy's objects."""
    entropy = [seed, zlib.crc32(name.encode()), stamp_ns % (1 << 64)]
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy)))


@pytest.mark.parametrize("seed", SEEDS)
def test_draws_are_numpy_seed_sequence_bits(seed: int) -> None:
    for name in NAMES:
        noise = Noise(seed, name)
        for stamp in STAMPS:
            expected = numpy_generator(seed, name, stamp).standard_normal(181)
            assert noise.normals(stamp, 181).tobytes() == expected.tobytes(), (name, stamp)


def test_state_is_pcg64_seeded_by_the_sequence() -> None:
    for seed in SEEDS:
        for stamp in STAMPS:
            entropy = [seed, zlib.crc32(b"robot/imu"), stamp % (1 << 64)]
            state = np.random.PCG64(np.random.SeedSequence(entropy)).state["state"]
            ours = pcg64_state([w for value in entropy for w in _words(value)])
            assert ours == (state["state"], state["inc"]), (seed, stamp)


def _words(value: int) -> list[int]:
    return [0] if value == 0 else [(value >> (32 * k)) & 0xFFFFFFFF
                                   for k in range((value.bit_length() + 31) // 32)]


def test_readings_do_not_depend_on_earlier_ones() -> None:
    """A reading's draws are the same whatever was drawn before (a replay that starts at
    a keyframe, or a sensor that drew more numbers at another stamp)."""
    noise = Noise(7, "robot/imu")
    first = noise.normals(40_000_000, 4)
    noise.normals(60_000_000, 181)
    noise.normals(80_000_000, 3)
    assert noise.normals(40_000_000, 4).tobytes() == first.tobytes()
    assert Noise(7, "robot/imu").normals(40_000_000, 4).tobytes() == first.tobytes()


def test_negative_seed_is_refused() -> None:
    with pytest.raises(ValueError, match="non-negative"):
        Noise(-1, "robot/imu")
