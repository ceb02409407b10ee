"""Checked conversion of what a user passes (tuples, lists, numpy arrays, ints) to the
plain floats a scene holds, with one-line errors that name the argument."""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Union

import numpy as np
import numpy.typing as npt

__all__ = ["Vec2", "VectorLike", "flag", "number", "scalar", "vector"]

Vec2 = tuple[float, float]
VectorLike = Union[Sequence[float], npt.NDArray[np.floating]]


def scalar(value: object) -> object:
    """``value``, or the item a 0-d numpy array holds (``np.array(2.0)``, what
    ``np.asarray`` makes of a number): one number, as a numpy scalar is, checked as one
    wherever the API takes a number, a switch or a count."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        return value[()]
    return value


def number(value: object, argument: str, *, positive: bool = False,
           minimum: Union[float, None] = None, maximum: Union[float, None] = None) -> float:
    """``value`` (a number, a numpy scalar or 0-d array) as a finite float; TypeError or
    ValueError naming ``argument``."""
    value = scalar(value)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise TypeError(f"{argument}: expected a number, not {type(value).__name__}")
    if isinstance(value, np.complexfloating):
        # float() would drop the imaginary part with a mere warning.
        raise TypeError(f"{argument}: expected a real number, not {type(value).__name__}")
    try:
        result = float(value)
    except OverflowError:  # an int past the largest double
        raise ValueError(f"{argument}: must be finite, not an integer of "
                         f"{len(str(abs(int(value))))} digits") from None
    if not math.isfinite(result):
        raise ValueError(f"{argument}: must be finite, not {result}")
    if positive and result <= 0.0:
        raise ValueError(f"{argument}: must be positive, not {result}")
    if minimum is not None and result < minimum:
        raise ValueError(f"{argument}: must be at least {minimum}, not {result}")
    if maximum is not None and result > maximum:
        raise ValueError(f"{argument}: must be at most {maximum}, not {result}")
    return result


def flag(value: object, argument: str) -> bool:
    """``value`` as a bool; TypeError naming ``argument`` for anything but True or False
    (numpy's too, a 0-d array of one): a string's truth is whether it is empty, so "false"
    would switch on."""
    value = scalar(value)
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{argument}: expected True or False, not {type(value).__name__}")
    return bool(value)


def vector(value: object, argument: str) -> Vec2:
    """``value`` (a tuple, list or numpy array of two numbers) as two floats."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise TypeError(f"{argument}: expected two numbers (x, y), not {type(value).__name__}")
    if isinstance(value, np.ndarray) and value.ndim != 1:
        # Raveling would read a (2, 1) column or a (1, 2) row as a vector by accident.
        raise ValueError(f"{argument}: expected two numbers (x, y), not an array of shape "
                         f"{value.shape}")
    items = list(value)
    if len(items) != 2:
        raise ValueError(f"{argument}: expected two numbers (x, y), not {len(items)}")
    return (number(items[0], argument), number(items[1], argument))
