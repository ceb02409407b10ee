"""Butcher tableaux of the embedded explicit Runge-Kutta pairs behind the adaptive methods.

Each pair has S slopes k_1..k_S: stage s (s = 2..S-1) is evaluated at
y + h (a_s1 k_1 + ... + a_s,s-1 k_s-1), the new state is y + h (b_1 k_1 + ... + b_S-1 k_S-1),
and k_S, evaluated at the new state, is the first slope of the next step ("first same as
last"). The error estimate is h times fixed combinations of the slopes: DOPRI5's uses k_S,
DOP853's does not (so it evaluates k_S only once a sub-step is accepted).

- ``DOPRI5``: Dormand and Prince's 5(4) pair (Dormand & Prince 1980), 6 new evaluations
  per step.
- ``DOP853``: Dormand and Prince's order-8 method with Hairer's 5th- and 3rd-order error
  estimates (Hairer, Norsett & Wanner, "Solving Ordinary Differential Equations I",
  Section II.10, code DOP853), 12 new evaluations per step. The coefficients are those of
  Hairer's DOP853 as published with SciPy (``scipy/integrate/_ivp/dop853_coefficients.py``,
  BSD licence), rounded to doubles.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["EmbeddedPair", "DOPRI5", "DOP853"]


@dataclass(frozen=True, eq=False)
class EmbeddedPair:
    """An explicit embedded Runge-Kutta pair with the first-same-as-last property.

    ``a`` is (S, S - 1): row s (0-based, s = 1..S-2) holds the coefficients of stage s + 1,
    row S - 1 the weights b of the new state. ``error`` is (m, S): each row a combination of
    all S slopes that, times h, estimates the local error (m = 1 or 2, see
    :meth:`error_norm`).
    """

    name: str
    order: int
    #: Order of the error estimate: the step size scales as norm ** (-1 / (error_order + 1)).
    error_order: int
    a: np.ndarray
    error: np.ndarray
    #: How far from 0 the stability region {z : |R(z)| <= 1} of the new state's weights
    #: reaches (R the pair's stability polynomial, rounded up): a sub-step dt lets a mode
    #: of rate r (an eigenvalue's size: a spring's frequency, a damper's decay rate) grow
    #: unless r dt is at most this.
    reach: float

    @property
    def slopes(self) -> int:
        return self.a.shape[0]

    @property
    def error_uses_new_state(self) -> bool:
        """True if the error estimate needs k_S, the slope at the new state."""
        return bool(np.any(self.error[:, -1] != 0.0))

    def error_norm(self, scaled: np.ndarray) -> float:
        """One number from the error estimates (rows of ``scaled``, each already divided by
        the tolerance scale): at most 1 means the step is accepted.

        One estimate: its root mean square. Two (DOP853's 5th- and 3rd-order estimates e5
        and e3): Hairer's combination |e5|^2 / sqrt(n (|e5|^2 + 0.01 |e3|^2)). For small
        steps |e3| >> |e5| and this is about 10 |e5|^2 / (sqrt(n) |e3|), of order h^8 (hence
        the error order 7); for large steps it tends to |e5| / sqrt(n). A sum of squares
        that overflows gives an infinite norm (the sub-step is refused), not a zero one.
        """
        if len(scaled) == 1:
            return float(np.sqrt(np.mean(scaled[0] ** 2)))
        e5, e3 = float(np.dot(scaled[0], scaled[0])), float(np.dot(scaled[1], scaled[1]))
        if not (math.isfinite(e5) and math.isfinite(e3)):
            return math.inf
        if e5 == 0.0:
            return 0.0
        return e5 / math.sqrt(scaled.shape[1] * (e5 + 0.01 * e3))


def _dense(rows: dict[int, dict[int, float]], shape: tuple[int, int]) -> np.ndarray:
    """A dense matrix from {row: {column: value}}."""
    matrix = np.zeros(shape)
    for i, row in rows.items():
        for j, value in row.items():
            matrix[i, j] = value
    return matrix


DOPRI5 = EmbeddedPair(
    "dopri5", 5, 4,
    a=np.array([
        [0, 0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
        [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
    ]),
    error=np.array([[71 / 57600, 0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525,
                     -1 / 40]]),
    reach=4.0,  # 3.98; 3.31 on the negative real axis
)

_DOP853_A = {  # row: {column: coefficient}, rows 1..11 the stages, row 12 the weights
    1: {0: 0.05260015195876773},
    2: {0: 0.0197250569845379, 1: 0.0591751709536137},
    3: {0: 0.02958758547680685, 2: 0.08876275643042054},
    4: {0: 0.2413651341592667, 2: -0.8845494793282861, 3: 0.924834003261792},
    5: {0: 0.037037037037037035, 3: 0.17082860872947386, 4: 0.12546768756682242},
    6: {0: 0.037109375, 3: 0.17025221101954405, 4: 0.06021653898045596, 5: -0.017578125},
    7: {0: 0.03709200011850479, 3: 0.17038392571223998, 4: 0.10726203044637328,
        5: -0.015319437748624402, 6: 0.008273789163814023},
    8: {0: 0.6241109587160757, 3: -3.3608926294469414, 4: -0.868219346841726, 5: 27.59209969944671,
        6: 20.154067550477894, 7: -43.48988418106996},
    9: {0: 0.47766253643826434, 3: -2.4881146199716677, 4: -0.590290826836843,
        5: 21.230051448181193, 6: 15.279233632882423, 7: -33.28821096898486,
        8: -0.020331201708508627},
    10: {0: -0.9371424300859873, 3: 5.186372428844064, 4: 1.0914373489967295,
         5: -8.149787010746927, 6: -18.52006565999696, 7: 22.739487099350505,
         8: 2.4936055526796523, 9: -3.0467644718982196},
    11: {0: 2.273310147516538, 3: -10.53449546673725, 4: -2.0008720582248625, 5: -17.9589318631188,
         6: 27.94888452941996, 7: -2.8589982771350235, 8: -8.87285693353063, 9: 12.360567175794303,
         10: 0.6433927460157636},
    12: {0: 0.054293734116568765, 5: 4.450312892752409, 6: 1.8915178993145003,
         7: -5.801203960010585, 8: 0.3111643669578199, 9: -0.1521609496625161,
         10: 0.20136540080403034, 11: 0.04471061572777259},
}
_DOP853_E5 = {0: 0.01312004499419488, 5: -1.2251564463762044, 6: -0.4957589496572502,
              7: 1.6643771824549864, 8: -0.35032884874997366, 9: 0.3341791187130175,
              10: 0.08192320648511571, 11: -0.022355307863886294}
_DOP853_E3 = {0: -0.18980075407240762, 5: 4.450312892752409, 6: 1.8915178993145003,
              7: -5.801203960010585, 8: -0.4226823213237919, 9: -0.1521609496625161,
              10: 0.20136540080403034, 11: 0.02265179219836082}

DOP853 = EmbeddedPair(
    "dop853", 8, 7,
    a=_dense(_DOP853_A, (13, 12)),
    error=_dense({0: _DOP853_E5, 1: _DOP853_E3}, (2, 13)),
    reach=7.13,  # 7.12; 6.38 on the negative real axis
)
