"""Joints: pins, sliders, welds, rods, ropes and gears, as constraints solved after each step.

A joint is a set of scalar constraints C(q) = 0 (or C(q) >= 0 for a limit or a rope) on the
bodies' CM positions and angles. Its rows' Jacobians follow from the body point velocity
v_P = v_CM + omega perp(r) (Eq. 9): a point constraint between P_A and P_B has the rows
(1, 0, -r_By) and (0, 1, r_Bx) on body B (and their negatives on A), an angle constraint
the row (0, 0, 1). An impulse lambda along a row changes a body's velocity by
M^-1 J^T lambda: the force part by Eq. 5, the torque of the impulse, perp(r) . P
(Eq. 11), turned into a change of angular velocity over inertia (Eq. 14), with the
moment of inertia of Eq. 13.

:class:`JointPass` runs after each integrator step, which has moved the bodies from
(q0, v0) to (q1, v1) under the smooth forces alone. It does what RATTLE does to a
constrained velocity Verlet step (Andersen 1983; Leimkuhler and Skeel 1994):

1. *Position, with velocity*: find the constraint impulse that, acting along the
   Jacobians at q0 (where the step began), brings q1 back to the constraints' values at
   q0, by Newton's method: q1 += M^-1 G(q0)^T nu. The velocity gets the same impulse,
   v1 += (that change of q1) / h, as RATTLE's first half kick does. With
   ``velocity_verlet`` this is RATTLE (second order, symplectic: the energy stays
   bounded); with another method of order two or more the pass is of order two.
2. *Drift, positions only*: whatever error q0 already had (left by the contact pass or by
   rounding), and any limit or rope passed, is removed by moving positions only
   (nonlinear Gauss-Seidel, as Box2D v2 and Chipmunk correct positions), so drift
   correction never adds kinetic energy.
3. *Velocity*: at the final positions, impulses make every rigid row's velocity zero
   (RATTLE's second half kick), limits' velocities at least -C/h (speculative: a joint may
   approach its limit as far as it reaches it at the next step's end), motors' velocities
   their target within their largest impulse (max effort x h), and soft rows (a revolute
   spring, a soft weld) follow the implicit spring-damper law of Box2D v3's soft step,
   lambda = -h (k C(q + h Cdot') + c Cdot').

Where the step is too long for stage 1, it is taken in parts. SHAKE's equations (stage 1)
lose their solution when the joints' arms turn far within a step, and on long chains even
at small turns: the Newton matrix G(q) M^-1 G(q0)^T changes sign along the iteration and
the iteration stalls (a 50-link chain folding at 0.5 rad a step; a 200-link chain at
h = 1/60 s, turning 0.02 rad a step: its weakest modes, condition numbers 1e5, move further
than the directions at q0 can follow). So the simulation takes a step in equal parts where
some joint's arm, axis or rod would turn by more than :data:`MAX_TURN` in it
(:meth:`JointPass.parts`), and in halves where stage 1's Newton iteration fails to halve
its error at every iteration or its solution turns a body by more than :data:`MAX_TURN`,
or where the last step's loads ring a body faster than :data:`MAX_RING` a step
(:meth:`JointPass.ringing`: a light chain holding a heavy body, whose tension makes each
link a stiff torsion spring that SHAKE takes explicitly) (:class:`JointsUnsolved`), in
:data:`MOST_SUBSTEPS` parts at most, then stops with a clear error. Where a step needed
halves, the next steps start in as many parts as it needed, and try half as many after
:data:`SETTLED_STEPS` steps that needed no more (:meth:`JointPass.remember`): a fast long
chain's steps in a row have no solution whole, and each whole attempt that fails costs
about as much as a part solved. A step that needs
none of this is RATTLE's, unchanged; a run whose steps take different numbers of parts is
not symplectic, and its energy can drift (docs/scenes.md, steps in parts).

The rigid rows of a stage are one block solved exactly; rows with bounds (limits, motors,
ropes) join the block where they hold their equations and sit at their bounds elsewhere,
the set found from the previous step's impulses in one or two factorizations (active
sets; projected Gauss-Seidel only where the sets do not settle: :mod:`.joint_solve`). The
blocks are factored in plain floats (no LAPACK, whose order of operations C could not
repeat), sparse, in an order the pass chooses from the joint graph, never from the
joints' names (:mod:`.sparse`): K = J M^-1 J^T by
L D L^T, the Newton matrix G(q) M^-1 G(q0)^T, not symmetric, by L U, both without
pivoting; a chain or a tree of joints fills nothing in and costs O(rows) per
factorization. A row that repeats what others hold (two pins at one point, the loops of a
grid) is dropped from the solve. Only the bodies some joint names take part. Revolute
angles are tracked across turns, so a gear keeps counting and a limit beyond pi works.

Why a pass of its own first, rather than rows in the contact solver's sequential impulses
alone: accuracy. A velocity-level solver is first order in the step, and the smooth-force
integrators (RK4, the embedded pairs, the implicit methods) cannot wrap one inside their
stages without dropping to first order; the projection above keeps order two with every
method of order two or more (docs/scenes.md has the measured periods). In every step and
contact sub-step the joints go first and the contacts last (they have the last word on
overlap); in each contact island that holds a jointed body the contact solver then sweeps
the velocity rows of this pass's last stage with the contacts (:mod:`.coupled`,
:meth:`JointPass.contact_units`), so that a contact force that depends on a joint's
reaction (a bar wedged between two pinned gears) comes out whole; what that leaves in the
positions the next step's joint pass corrects, by positions only.

The rows' Jacobians are built by :mod:`.joint_rows`. The compiled kernel's
``src/kernel/joint.c`` (with ``src/kernel/sparse.c``) repeats this module and those two
operation for operation (:mod:`.joints_kernel` packs it), so both give the same
bits.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Optional, Union

import numpy as np

from ..scene.joints import (
    DistanceJoint,
    GearJoint,
    JointSpec,
    Motor,
    PrismaticJoint,
    RevoluteJoint,
    WeldJoint,
)
from ..scene.parameters import number_text
from .coupled import JointUnit
from .joint_rows import (
    EFFORT_SIGNS,
    LIMIT,
    MOTOR,
    RIGID,
    SOFT,
    Frame,
    JointRow,
    Point,
    Vec2,
    angle_entries,
    bounded_rows,
    fixed_entries,
    line_entries,
    negated,
    point_rows,
    weld_law,
    wrap,
)
from .joint_solve import Directions, apply, directions, dot, matrix, rate, refine, solve
from .sparse import Factors, Pattern, factor, joint_order, lu, lu_solve, substitute

if TYPE_CHECKING:
    from ..scene.load import Scene
    from .joints_kernel import CompiledJoints

__all__ = ["CARRIED", "GEAR_ADVICE_RATIO", "UNSOLVED", "UNSOLVED_ADVICE", "JointPass",
           "JointsUnsolved", "MAX_RING", "MAX_TURN", "MOST_SUBSTEPS", "PARTS", "RATING_BOUND",
           "SETTLED_STEPS", "SHARE_ABOVE", "ringing_advice", "unsolved_advice"]

#: A constraint error (m or rad) counted as met by the position stages.
TOLERANCE = 1e-12
#: Below this times (1 + the largest coordinate) the rows' values are rounding: the position
#: stages ask no smaller error of them.
ROUNDING = 16.0 * 2.220446049250313e-16
NEWTON_ITERATIONS = 50
#: A Newton step on an earlier iterate's matrix must cut the error by this much, or the
#: next step takes its own iterate's matrix.
CHORD = 0.125
#: The most a step may turn a joint's arm (rad), by the bodies' own motion or by the joints'
#: correction: a step that would is taken in parts (:meth:`JointPass.parts`) or halves.
MAX_TURN = 0.1
#: The most a step may advance the fastest ring its joints' loads can drive (rad: h omega,
#: :meth:`JointPass.ringing`'s rating of omega): a step that would is taken in halves. SHAKE
#: takes a load's arm at the step's start, so the torsional stiffness a tension gives a
#: light link is explicit, and velocity Verlet grows any oscillation with h omega > 2; 1,
#: not 2, because steps whose parts change pump a ring near 2 (a chain of 1 kg links ending
#: in 1e4 kg at h = 1/240 s: 2.5e-5 of its energy scale in 10 s at 1, 22 % at 2).
MAX_RING = 1.0
#: What :meth:`JointPass.ringing`'s bound of its rating is multiplied by, above 1 by far more
#: than the rounding of the rating's sums (a few units in the last place).
RATING_BOUND = 1.0 + 1e-9
#: The most parts a step is taken in, in all (ten halvings), before the joints give up.
MOST_SUBSTEPS = 1024
#: Steps in a row that stage 1 solves in the parts remembered from an earlier failure
#: (:meth:`JointPass.remember`) before a step tries half as many again.
SETTLED_STEPS = 4
DRIFT_ITERATIONS = 8
#: Where factoring the rows costs more than this many times their factor's entries
#: (:meth:`.sparse.Pattern.updates` over slots) and every row is rigid, the velocity stage
#: refines its solve on the Newton matrix's L U instead of factoring K
#: (:func:`.joint_solve.refine`, :attr:`JointPass.share`): a correction costs about four
#: multiply-adds a slot, so two or three of them pay where a factorization costs more than
#: eight a slot (grids of pins: 12 at 10 x 10, 62 at 100 x 100; chains and trees under 5).
SHARE_ABOVE = 8
#: Why a step failed when its parts ran out, and what helps; one text for both paths. Fast
#: turns leave no solution near a part's end; joined masses far apart (the measured limit
#: on a 10-link chain of alternating masses at h = 1/240 s lies between 1e14 and 1e15 to
#: one) move a light body by the difference of its heavy neighbours' multipliers, which
#: rounding leaves above TOLERANCE.
UNSOLVED = f"the joints have no solution near the end of the step, taken in {MOST_SUBSTEPS} parts"
UNSOLVED_ADVICE = ("the bodies turn too fast for the step, or the masses joined are too far "
                   "apart (beyond about 1e14 to one); take a shorter step, or masses closer "
                   "together")

#: A gear's ratio past which a step the joints give up on names the gear: its row is
#: angle_a + ratio angle_b, whose rounding grows with the ratio (two wheels of 2 and 8 kg
#: at 1 ms: ratio 1e3 runs, 1e4 has no solution), while the same gear written the other
#: way round, ratio 1 / ratio, runs (1e-12 too).
GEAR_ADVICE_RATIO = 100.0


def unsolved_advice(scene: Scene) -> str:
    """What helps a step whose parts ran out: :data:`UNSOLVED_ADVICE`, or, for a scene
    with a gear whose ratio passes :data:`GEAR_ADVICE_RATIO` (the largest), that gear
    written the other way round, which the user can change without changing the
    motion."""
    gears = [spec for spec in scene.joints
             if isinstance(spec, GearJoint) and abs(spec.ratio) > GEAR_ADVICE_RATIO]
    if not gears:
        return UNSOLVED_ADVICE
    gear = max(gears, key=lambda spec: abs(spec.ratio))
    return (f"the bodies turn too fast for the step, or gear '{gear.name}' ties its joints "
            f"at a ratio of {gear.ratio:.6g}, which its row's rounding grows with; "
            f"write it the other way round, the same gear (joint_a: {gear.joint_b}, "
            f"joint_b: {gear.joint_a}, ratio: {number_text(1.0 / gear.ratio)}), or take a "
            "shorter step")


def ringing_advice(omega: float) -> str:
    """Why a step failed when its parts ran out on the ring of :meth:`JointPass.ringing`
    (``omega``, rad/s), and the step that needs no parts for it (h omega < 2)."""
    return (f"the joints' loads ring a body at {omega:.3g} rad/s (a chain's tension turning "
            f"its links against each other: a light body under a heavy load, or a chain held "
            f"straight, whose tension has no bound), faster than {MOST_SUBSTEPS} parts of the "
            f"step can follow; take a step below {2.0 / omega:.3g} s, heavier bodies under "
            f"the load, or slack in a straight chain")


#: The attributes of :class:`JointPass` that carry from step to step and that the compiled
#: kernel keeps between its calls (:meth:`JointPass.kernel_pass`).
CARRIED = ("angle", "raw", "warm", "newton", "extra", "step_h", "efforts")
#: The parts a whole step starts in and the steps since (:meth:`JointPass.remember`), carried
#: too: the kernel's whole steps change them; around its resolve alone the simulation does.
PARTS = ("remembered", "settled_steps")


class JointsUnsolved(ArithmeticError):
    """The joints' positions have no solution near the end of a step this long (see
    :meth:`JointPass._hold`): the step must be taken in shorter parts."""


#: Joint kinds in the order that breaks a tie between joints anchored at one point.
_KINDS = (RevoluteJoint, PrismaticJoint, WeldJoint, DistanceJoint, GearJoint)


def _solve_order(scene: Scene, specs: tuple[JointSpec, ...]) -> tuple[JointSpec, ...]:
    """The joints in the order :func:`.sparse.joint_order` gives the joint graph: two
    joints are neighbours when their rows act on a common body (a gear's rows act on the
    bodies of its two joints); ties go to the anchor (body_b's point at the start, a
    gear's the mean of its joints') first in x, then y, then the kind, then the name."""
    bodies = {body.name: body for body in scene.bodies}
    named = {spec.name: spec for spec in specs}

    def ends(spec: JointSpec) -> set[str]:
        if isinstance(spec, GearJoint):
            return ends(named[spec.joint_a]) | ends(named[spec.joint_b])
        return {n for n in (spec.body_a, spec.body_b) if n is not None}

    def anchor(spec: JointSpec) -> tuple[float, float]:
        if isinstance(spec, GearJoint):
            (xa, ya), (xb, yb) = anchor(named[spec.joint_a]), anchor(named[spec.joint_b])
            return 0.5 * (xa + xb), 0.5 * (ya + yb)
        body = bodies[spec.body_b]
        c, s = math.cos(body.angle), math.sin(body.angle)
        px, py = spec.point_b
        return body.position[0] + c * px - s * py, body.position[1] + s * px + c * py

    held = [ends(spec) for spec in specs]
    on_body: dict[str, list[int]] = {}
    for i, names in enumerate(held):
        for name in names:
            on_body.setdefault(name, []).append(i)
    neighbours = [{j for name in names for j in on_body[name]} - {i}
                  for i, names in enumerate(held)]
    keys = [(*anchor(spec), _KINDS.index(type(spec)), i) for i, spec in enumerate(specs)]
    # A joint between two bodies already joined closes a loop (union-find over the bodies;
    # a gear joins its two joints' bodies).
    root: dict[str, str] = {}

    def find(name: str) -> str:
        while root.setdefault(name, name) != name:
            name = root[name]
        return name

    loops = False
    for names in held:
        first, *others = sorted(names)
        for other in others:
            a, b = find(first), find(other)
            loops = loops or a == b
            root[b] = a
    return tuple(specs[i] for i in joint_order(neighbours, keys, loops))


def _on_loops(bodies: int, joined: list[tuple[int, int]]) -> list[int]:
    """Per body, how many of its joints lie on closed loops of joints (or on paths between
    two), the fixed frame (-1) one node: its joints among what is left after the bodies and
    the frame held by one joint or none are taken away, again and again (the graph's
    2-core, which is one whatever the order), 0 for a body taken away. A chain or a tree of
    joints leaves nothing; a bridge anchored at both ends leaves itself, each plank with 2;
    a grid leaves itself, its bodies with 3 or 4 (its bottom corners with 2)."""
    frame = bodies
    neighbours: list[list[int]] = [[] for _ in range(bodies + 1)]
    for a, b in joined:
        a = frame if a < 0 else a
        neighbours[a].append(b)
        neighbours[b].append(a)
    joints = [len(n) for n in neighbours]
    left = [True] * (bodies + 1)
    loose = [node for node, count in enumerate(joints) if count <= 1]
    while loose:
        node = loose.pop()
        left[node] = False
        for other in neighbours[node]:
            if left[other]:
                joints[other] -= 1
                if joints[other] == 1:
                    loose.append(other)
    return [count if on else 0 for count, on in zip(joints[:bodies], left)]


def _row_tolerance(gap: float) -> float:
    """The tolerance of each row that holds every pin's two points within ``gap`` (m): the
    position stages test each row against it, and a pin's x and y rows, each within it,
    leave its points up to sqrt(2) times it apart (both rows at the tolerance: 1.27e-9 to
    1.31e-9 m on the 50- and 200-link chains held to 1e-9 m a row)."""
    return gap / math.sqrt(2.0)


class JointPass:
    """The scene's joints, solved after each integrator step (see the module docstring)."""

    #: The equal sub-steps every step is taken in, each with its own pass (soft joints,
    #: :mod:`.soft_joints`); 0: this pass, in the parts :meth:`parts` asks for.
    substeps = 0

    def __init__(self, scene: Scene, inverse_mass: np.ndarray, cm_local: np.ndarray,
                 compiled: bool = False) -> None:
        """The joints of ``scene``, whose bodies have the inverse masses and moments of
        inertia ``inverse_mass`` (rows 1/m, 1/m, 1/I) and their CMs at ``cm_local`` in their
        body frames; ``compiled``: resolve in the kernel (:mod:`.joints_kernel`), which must
        be built."""
        specs = scene.joints
        named = {spec.name: spec for spec in specs}
        index = {body.name: i for i, body in enumerate(scene.bodies)}

        def local(body: int, point: Vec2) -> Vec2:  # body-frame point -> offset from the CM
            x, y = (np.asarray(point, dtype=float) - cm_local[body]).tolist()
            return x, y

        involved = sorted({index[n] for spec in specs if not isinstance(spec, GearJoint)
                           for n in (spec.body_a, spec.body_b) if n is not None})
        #: Indices (in the scene) of the bodies some joint holds; rows use their positions.
        self.bodies = np.array(involved, dtype=int)
        local_index = {body: i for i, body in enumerate(involved)}
        #: The joints in the order their rows are solved in (:func:`_solve_order`).
        self.specs = _solve_order(scene, specs)
        self._named = named
        #: Each motor (its largest effort; the speed it is commanded is in motor_speed).
        self.motors = {s.name: s.motor for s in specs
                       if isinstance(s, (RevoluteJoint, PrismaticJoint)) and s.motor}
        self.frames: dict[str, tuple[Frame, Frame]] = {}
        for spec in specs:
            if isinstance(spec, GearJoint):
                continue
            ia = -1 if spec.body_a is None else index[spec.body_a]
            ib = index[spec.body_b]
            point_a = (spec.point_a[0], spec.point_a[1]) if ia < 0 else local(ia, spec.point_a)
            self.frames[spec.name] = (Frame(-1 if ia < 0 else local_index[ia], point_a),
                                      Frame(local_index[ib], local(ib, spec.point_b)))
        self._gears = {spec.name: (named[spec.joint_a], named[spec.joint_b])
                       for spec in specs if isinstance(spec, GearJoint)}
        # What :meth:`parts` watches: the bodies whose turning turns a joint's arm or axis
        # (those a joint holds off their CM, a slider's body_a), and the rods and ropes,
        # whose direction runs between their points.
        turning = {f.body for name, ends in self.frames.items() for f in ends if f.body >= 0
                   and (f.local != (0.0, 0.0) or
                        (f is ends[0] and isinstance(named[name], PrismaticJoint)))}
        #: The scene indices of the bodies whose turning :meth:`parts` watches.
        self.turning = self.bodies[sorted(turning)]
        self._rods = [self.frames[s.name] for s in self.specs if isinstance(s, DistanceJoint)]
        #: The constraint error (m or rad) the position stages count as met, row by row (a
        #: pin's x and y rows each: its ends within sqrt(2) times it; :meth:`hold_pins_within`,
        #: the scene's ``joint_solver.pin_gap``).
        self.tolerance = TOLERANCE if scene.pin_gap is None else _row_tolerance(scene.pin_gap)
        #: The most a joint's arm may turn in a step or part (rad): :data:`MAX_TURN`.
        self.max_turn = MAX_TURN
        #: The largest error of the last Newton iteration's first iterate (:meth:`_newton`).
        self.first_error = math.inf
        #: 1/m, 1/m, 1/I of each of those bodies.
        self.inverse_mass: list[float] = inverse_mass[self.bodies].reshape(-1).tolist()
        looped = _on_loops(len(involved), [(a.body, b.body) for a, b in self.frames.values()])
        #: Per body, 1/I where its turn is its own, else 0 (a fixed body, or one that three or
        #: more joints on closed loops hold, a knot of a grid's frame): the bodies
        #: :meth:`ringing` rates, and those whose turn holds a neighbour's there.
        self.free_turn = [0.0 if on > 2 else self.inverse_mass[3 * b + 2]
                          for b, on in enumerate(looped)]
        #: Pairs of body indices (i < j) that a joint connects and that must not collide.
        ends = [(index[s.body_a], index[s.body_b]) for s in specs
                if not isinstance(s, GearJoint) and s.body_a is not None
                and not s.collide_connected]
        self.connected: list[tuple[int, int]] = sorted({(min(i, j), max(i, j))
                                                        for i, j in ends})
        self._initial: Optional[np.ndarray] = None
        #: The last velocity stage's rows and their directions M^-1 J^T.
        self._last: tuple[list[JointRow], Directions] = ([], [])
        #: The velocities (3 per body) before the last velocity stage: those the
        #: positions moved with.
        self._settled: list[float] = []
        self.rigid: list[int] = []
        self._kernel: Optional[CompiledJoints] = None  # made at the first step
        #: Where the factors of all rows' matrices, and of the rigid rows' alone, can be
        #: non-zero (:class:`.sparse.Pattern`), once the start pose has fixed the rows.
        self.pattern: Optional[Pattern] = None
        self.rigid_pattern = Pattern((0,), (), ())
        #: Whether the velocity stage refines on the Newton matrix's L U (:data:`SHARE_ABOVE`).
        self.share = False
        #: The last Newton matrix's L U and U's strict upper triangle, while this pass's
        #: positions are those it was solved for (the velocity stage's start in refining).
        self._near: Optional[tuple[Factors, list[float]]] = None
        #: Each row's (joint, part), in the order the rows come at any pose.
        self.keys: list[tuple[str, str]] = []
        #: Each row's kind (:data:`RIGID`, ...), in the same order.
        self.kinds: list[str] = []
        self.reset()
        self._compiled = compiled

    @property
    def compiled(self) -> bool:
        """True while the pass resolves in the compiled kernel."""
        return self._compiled

    def hold_pins_within(self, gap: float) -> None:
        """Hold every pin's two points within ``gap`` (m) of each other, the distance a user
        measures between them (:func:`~hecker_dynamics.bench.joints.pin_gap`), and every
        other row within ``gap``: a looser ``gap`` than the default's costs less (issue 33;
        the scene's ``joint_solver.pin_gap`` asks for the same from the start). The
        tolerance becomes ``gap`` / sqrt(2) (:func:`_row_tolerance`). Raises ValueError for
        a ``gap`` that is not a positive number."""
        if isinstance(gap, bool) or not isinstance(gap, (int, float)) or not gap > 0.0 \
                or not math.isfinite(gap):
            raise ValueError(f"a pin gap must be a positive number of metres, not {gap!r}")
        self._changing()
        self.tolerance = _row_tolerance(gap)
        self._kernel = None  # the kernel's pass took the tolerance when made: made anew

    def use_python(self) -> None:
        """Resolve in Python from now on."""
        self._take_back()
        self._compiled, self._kernel = False, None

    if not TYPE_CHECKING:  # typed as the attributes they stand for
        def __getattr__(self, name: str) -> Any:
            """A :data:`CARRIED` or :data:`PARTS` attribute while the kernel holds it newer
            (they are absent then): read back from the kernel, all at once, on the first
            read after its steps."""
            kernel = self.__dict__.get("_kernel")
            if name not in CARRIED + PARTS or kernel is None or not kernel.ahead:
                raise AttributeError(f"'{type(self).__name__}' object has no attribute "
                                     f"'{name}'")
            kernel.take_back()
            return self.__dict__[name]

    def _take_back(self) -> None:
        """Read the state back from the kernel if it holds it newer."""
        if self._kernel is not None:
            self._kernel.take_back()

    def _changing(self) -> None:
        """Before this pass's state is changed here: read it back from the kernel, which
        takes it anew before its next call."""
        if self._kernel is not None:
            self._kernel.take_back()
            self._kernel.loaded = False

    def _in_kernel(self) -> CompiledJoints:
        """The kernel's pass, made once the start pose has fixed the rows."""
        if self._kernel is None:
            from .joints_kernel import CompiledJoints
            self._kernel = CompiledJoints(self)
        return self._kernel

    def kernel_pass(self) -> Any:
        """The kernel's joint pass (a capsule) holding this pass's state, for whole steps
        in the kernel; :meth:`kernel_done` follows them. The state stays in the kernel
        from call to call: it is loaded from this object only after it changed here
        (:meth:`reset`, :meth:`forget`, :meth:`import_state`), else passed through an
        array with the motor speeds and the parts this object keeps (copies in C), and
        read back only when read (:data:`CARRIED`, :data:`PARTS`), so that a scene of many
        joints stepped call by call does not move all their state through Python at every
        call."""
        compiled = self._in_kernel()
        compiled.begin()
        return compiled.kernel

    def kernel_done(self) -> None:
        """After steps :meth:`kernel_pass` began: the kernel's state is the newer."""
        self._in_kernel().end(whole=True)

    def restore(self, warm: list[float], newton: Optional[list[float]], step_h: float) -> None:
        """Take the warm starts, Newton multipliers and last step length the kernel left."""
        self.warm, self.newton, self.step_h = warm, newton, step_h
        self._set_efforts()

    # ------------------------------------------------------------------ state

    def reset(self, q: Optional[np.ndarray] = None) -> None:
        """Forget warm-start impulses; take ``q`` (all bodies) as the joints' start pose,
        where joint angles and slider translations are zero (default: the last one)."""
        if q is not None:
            self._initial = q[self.bodies].copy()
        self.forget()
        self.efforts: dict[str, float] = {}
        #: Each motor's target speed, which a command may change between steps.
        self.motor_speed = {s.name: s.motor.speed for s in self.specs
                            if isinstance(s, (RevoluteJoint, PrismaticJoint)) and s.motor}
        if self._initial is None:
            return
        start = self._initial.reshape(-1).tolist()
        self.reference = {}  # per joint: initial relative angle and translation
        self.raw: dict[str, float] = {}
        self.angle: dict[str, float] = {}
        for name, (a, b) in self.frames.items():
            pa, pb = a.place(start), b.place(start)
            relative = pb[4] - pa[4]
            spec = self._named[name]
            along = 0.0
            if isinstance(spec, PrismaticJoint):
                ux, uy = self._axis(spec, pa[4])
                along = ux * (pb[0] - pa[0]) + uy * (pb[1] - pa[1])
            self.reference[name] = (relative, along)
            self.raw[name], self.angle[name] = relative, 0.0
        # Every joint gives the same rows in the same order at any pose.
        template = self.rows(start, 1.0)
        self.rigid = [i for i, r in enumerate(template) if r.kind == RIGID]
        if self.pattern is None:  # where the factors can be non-zero: the same at any pose
            shares = [[jx * dx + jy * dy + jw * dw
                       for (_, jx, jy, jw), (_, dx, dy, dw) in zip(row.entries, towards)]
                      for row, towards in zip(template, directions(template, self.inverse_mass))]
            self.pattern = Pattern.of([[e[0] for e in r.entries] for r in template]).lightest(
                shares)
            self.rigid_pattern = Pattern.of([[e[0] for e in template[i].entries]
                                             for i in self.rigid]).lightest(
                [shares[i] for i in self.rigid])
            self.share = (len(self.rigid) == len(template)
                          and self.pattern.updates() > SHARE_ABOVE * self.pattern.slots())
        self.keys = [r.key for r in template]
        self.kinds = [r.kind for r in template]
        #: The first (x) row of each rigid point's two rows, x then y (:meth:`ringing`).
        self.pins = [i for i, ((_, part), kind) in enumerate(zip(self.keys, self.kinds))
                     if kind == RIGID and part == "x"]
        #: Per body, its pins in that order (:meth:`ringing`): the pin's point on it (from
        #: its CM), the body at the pin's other end (-1: the fixed frame) and that end's arm.
        self.pinned: list[list[tuple[Vec2, int, float]]] = [[] for _ in self.bodies]
        for i in self.pins:
            ends = self.frames[self.keys[i][0]]
            for mine, other in (ends, ends[::-1]):
                if mine.body >= 0:
                    x, y = other.local
                    self.pinned[mine.body].append((mine.local, other.body,
                                                   math.sqrt(x * x + y * y)))
        self.warm = [0.0] * len(template)
        self.extra = [0.0] * len(template)

    def forget(self) -> None:
        """Drop what warm-starts the next step (after a body was moved by hand)."""
        self._changing()
        self.warm = [0.0] * len(self.keys)
        #: The extra impulses the last contact solve added (:meth:`take_extra`).
        self.extra = [0.0] * len(self.keys)
        self.newton = None
        self.step_h = 1.0
        #: The parts a step starts in (:meth:`remember`), the steps in a row that needed no
        #: more, and the parts the step under way has needed so far.
        self.remembered, self.settled_steps, self.needed = 1, 0, 1

    def export_state(self) -> dict[str, Any]:
        """What the pass carries from step to step, as plain data: the start pose, the
        counted joint angles, the warm-start impulses and Newton multipliers with the step
        they were taken over, the parts remembered, the efforts and motor speeds."""
        return {"initial": None if self._initial is None else self._initial.tolist(),
                "angle": dict(self.angle) if self._initial is not None else {},
                "raw": dict(self.raw) if self._initial is not None else {},
                "warm": [[list(key), value] for key, value in zip(self.keys, self.warm)],
                "newton": None if self.newton is None else list(self.newton),
                "step_h": self.step_h, "parts": [self.remembered, self.settled_steps],
                "extra": [[list(key), value] for key, value in zip(self.keys, self.extra)],
                "efforts": dict(self.efforts), "motor_speed": dict(self.motor_speed)}

    def import_state(self, state: dict[str, Any]) -> None:
        """Restore :meth:`export_state`'s data."""
        if state["initial"] is not None:
            self._initial = np.array(state["initial"], dtype=float)
        self.reset()
        if self._initial is not None:
            self.angle = {k: float(x) for k, x in state["angle"].items()}
            self.raw = {k: float(x) for k, x in state["raw"].items()}
        warm = {(str(a), str(b)): float(x) for (a, b), x in state["warm"]}
        self.warm = [warm.get(key, 0.0) for key in self.keys]
        extra = {(str(a), str(b)): float(x) for (a, b), x in state.get("extra", [])}
        self.extra = [extra.get(key, 0.0) for key in self.keys]
        self.newton = (None if state["newton"] is None
                        else [float(x) for x in state["newton"]])
        self.step_h = float(state.get("step_h", self.step_h))
        self.remembered, self.settled_steps = (int(n) for n in state.get("parts", (1, 0)))
        self.efforts = {k: float(x) for k, x in state["efforts"].items()}
        self.motor_speed.update({k: float(x) for k, x in state["motor_speed"].items()})

    def _axis(self, spec: PrismaticJoint, angle_a: float) -> tuple[float, float]:
        c, s = math.cos(angle_a), math.sin(angle_a)
        return c * spec.axis[0] - s * spec.axis[1], s * spec.axis[0] + c * spec.axis[1]

    def _joint_angle(self, name: str, pa: Point, pb: Point) -> float:
        """body_b's angle relative to body_a's since the start, counting whole turns."""
        raw = pb[4] - pa[4]
        return self.angle[name] + wrap(raw - self.raw[name])

    def joint_state(self, q: np.ndarray, v: np.ndarray) -> dict[str, tuple[float, float, float]]:
        """(position, velocity, effort) of each revolute (rad, rad/s, N m) and prismatic
        (m, m/s, N) joint at the state (q, v) of all bodies: the fields of
        sensor_msgs/JointState. The effort is the last step's motor, limit and spring
        impulse along the joint over the step."""
        mine, vel = q[self.bodies].reshape(-1).tolist(), v[self.bodies].reshape(-1).tolist()
        state = {}
        for spec in self.specs:
            if not isinstance(spec, (RevoluteJoint, PrismaticJoint)):
                continue
            row = self._coordinate(spec, mine)
            rate = sum(jx * vel[3 * b] + jy * vel[3 * b + 1] + jw * vel[3 * b + 2]
                       for b, jx, jy, jw in row.entries)
            state[spec.name] = (row.c, rate, self.efforts.get(spec.name, 0.0))
        return state

    def _coordinate(self, spec: Union[RevoluteJoint, PrismaticJoint], q: list[float]) -> JointRow:
        """The joint's coordinate (angle or translation) at ``q`` as a row."""
        a, b = self.frames[spec.name]
        pa, pb = a.place(q), b.place(q)
        if isinstance(spec, RevoluteJoint):
            return JointRow((spec.name, "angle"), MOTOR, self._joint_angle(spec.name, pa, pb),
                            angle_entries(a.body, b.body))
        ux, uy = self._axis(spec, pa[4])
        along = ux * (pb[0] - pa[0]) + uy * (pb[1] - pa[1]) - self.reference[spec.name][1]
        return JointRow((spec.name, "along"), MOTOR, along, line_entries(a, b, pa, pb, ux, uy))

    # ------------------------------------------------------------------ rows

    def rows(self, q: list[float], h: float) -> list[JointRow]:
        """Every joint's rows at positions ``q`` (the joint bodies only, local order)."""
        rows: list[JointRow] = []
        for spec in self.specs:
            if isinstance(spec, GearJoint):
                rows.append(self._gear_row(spec, q))
                continue
            a, b = self.frames[spec.name]
            pa, pb = a.place(q), b.place(q)
            name = spec.name
            if isinstance(spec, RevoluteJoint):
                rows += point_rows(name, a, b, pa, pb, RIGID)
                angle = self._joint_angle(name, pa, pb)
                entries = angle_entries(a.body, b.body)
                rows += bounded_rows(name, angle, entries, spec.lower, spec.upper,
                                      self._motor(spec), h)
                if spec.spring is not None:
                    rows.append(JointRow((name, "spring"), SOFT,
                                         angle - spec.spring.rest_angle, entries,
                                         stiffness=spec.spring.stiffness,
                                         damping=spec.spring.damping))
            elif isinstance(spec, WeldJoint):
                kind = SOFT if spec.frequency > 0.0 else RIGID
                k, c = weld_law(spec)
                rows += point_rows(name, a, b, pa, pb, kind, k, c)
                relative = wrap(pb[4] - pa[4] - self.reference[name][0])
                rows.append(JointRow((name, "angle"), kind, relative,
                                     angle_entries(a.body, b.body), stiffness=k, damping=c,
                                     scaled=True))
            elif isinstance(spec, PrismaticJoint):
                ux, uy = self._axis(spec, pa[4])
                across = -uy * (pb[0] - pa[0]) + ux * (pb[1] - pa[1])
                rows.append(JointRow((name, "across"), RIGID, across,
                                     line_entries(a, b, pa, pb, -uy, ux)))
                relative = wrap(pb[4] - pa[4] - self.reference[name][0])
                rows.append(JointRow((name, "angle"), RIGID, relative,
                                     angle_entries(a.body, b.body)))
                along = self._coordinate(spec, q)
                rows += bounded_rows(name, along.c, along.entries, spec.lower, spec.upper,
                                      self._motor(spec), h)
            else:  # DistanceJoint
                dx, dy = pb[0] - pa[0], pb[1] - pa[1]
                length = math.sqrt(dx * dx + dy * dy)  # as C computes it
                ux, uy = (dx / length, dy / length) if length > 0.0 else (1.0, 0.0)
                entries = fixed_entries(a, b, pa, pb, ux, uy)  # d|d| = u . d(P_B - P_A)
                if spec.rope:
                    rows.append(JointRow((name, "rope"), LIMIT, spec.length - length,
                                         negated(entries)))
                else:
                    rows.append(JointRow((name, "rod"), RIGID, length - spec.length, entries))
        return rows

    def _motor(self, spec: Union[RevoluteJoint, PrismaticJoint]) -> Optional[Motor]:
        """The joint's motor at the speed commanded now (:attr:`motor_speed`)."""
        if spec.motor is None:
            return None
        return Motor(self.motor_speed[spec.name], spec.motor.max_effort)

    def _gear_row(self, spec: GearJoint, q: list[float]) -> JointRow:
        """angle_a + ratio angle_b = 0 over the two revolute joints' bodies."""
        value, entries = 0.0, []
        for joint, scale in ((self._gears[spec.name][0], 1.0), (self._gears[spec.name][1],
                                                               spec.ratio)):
            a, b = self.frames[joint.name]
            value += scale * self._joint_angle(joint.name, a.place(q), b.place(q))
            entries += angle_entries(a.body, b.body, scale)
        return JointRow((spec.name, "gear"), RIGID, value, entries)

    # ------------------------------------------------------------------ the pass

    def parts(self, q0: np.ndarray, q1: np.ndarray) -> int:
        """How many equal parts a step from ``q0`` to ``q1`` (all bodies, before this pass)
        is to be taken in so that no joint's arm or axis, nor a rod's or rope's direction,
        turns by more than :data:`MAX_TURN` in a part (at most :data:`MOST_SUBSTEPS`): 1 when
        none turns further. The joints' correction is second order in that turn: RATTLE's
        error, and the reach of its Newton iteration, follow from it."""
        turn = 0.0
        for k in self.turning.tolist():
            turn = max(turn, abs(q1[k, 2] - q0[k, 2]))
        if self._rods:
            start = q0[self.bodies].reshape(-1).tolist()
            end = q1[self.bodies].reshape(-1).tolist()
            for a, b in self._rods:
                (xa, ya, *_), (xb, yb, *_) = a.place(start), b.place(start)
                (ua, va, *_), (ub, vb, *_) = a.place(end), b.place(end)
                dx, dy, ex, ey = xb - xa, yb - ya, ub - ua, vb - va
                turn = max(turn, math.atan2(abs(dx * ey - dy * ex), dx * ex + dy * ey))
        if not turn > self.max_turn:  # within, or not finite: the divergence check reports it
            return 1
        parts = turn / self.max_turn
        return MOST_SUBSTEPS if parts >= MOST_SUBSTEPS else max(math.ceil(parts), 2)

    def remember(self) -> None:
        """After a whole step (:attr:`needed`: the most parts a failure of stage 1 asked
        for): where it needed more parts than :attr:`remembered`, the next steps start in
        that many; after :data:`SETTLED_STEPS` steps in a row that needed no more, in half
        as many."""
        if self.needed > self.remembered:
            self.remembered, self.settled_steps = self.needed, 0
        elif self.remembered > 1:
            self.settled_steps += 1
            if self.settled_steps == SETTLED_STEPS:
                self.remembered, self.settled_steps = self.remembered // 2, 0
        self.needed = 1

    def resolve(self, q0: np.ndarray, q1: np.ndarray, v1: np.ndarray, h: float) -> None:
        """Constrain the step from ``q0`` to (``q1``, ``v1``) of length ``h``; updates
        ``q1`` and ``v1`` (all bodies) in place."""
        if self._initial is None:
            self.reset(q0)
        index = self.bodies
        if self._compiled:
            self._in_kernel().resolve(q0, q1, v1, h)
            return
        start = q0[index].reshape(-1).tolist()
        rows0 = self.rows(start, h)
        if h * h * self.ringing(rows0, h) > MAX_RING * MAX_RING:
            raise JointsUnsolved(f"the joints' loads ring a body too fast for a step of {h:g} s")
        q = q1[index].reshape(-1).tolist()
        moved = list(q)
        rows = self._hold(rows0, q, h)
        v = v1[index].reshape(-1).tolist()
        for k, (now, before) in enumerate(zip(q, moved)):
            v[k] += (now - before) / h
        rows = self._correct(rows, q, h)
        self._settled = v[:]
        self._velocities(rows, v, h)
        self._count_turns(q)
        q1[index] = np.array(q).reshape(-1, 3)
        v1[index] = np.array(v).reshape(-1, 3)

    def ringing(self, rows: list[JointRow], h: float = 0.0) -> float:
        """omega^2 (1/s^2) of the fastest ring the last step's loads on the pins drive, the
        bodies at the pose of ``rows``, as rated body by body; given a step ``h``, a bound
        of it instead where h omega stays below :data:`MAX_RING` on the bound (below). A
        load F on a point at arm r from a body's CM turns with the body: its torque
        perp(r) . F (Eq. 11) changes by -(r . F) per radian the body turns, so the loads give the
        body a torsional stiffness k = sum of r . F over its pins (positive where they pull
        its points away from its CM: a link of a chain under a tension T, k = T l, l its
        length). A body rings with its neighbours: it turns about its CM while each
        neighbour turns about its own CM to follow the pin they share (a chain's zigzag), or
        it turns about one of its pins while the neighbour there stays; each such motion
        rings at the sum of the stiffnesses it turns over the sum of the moments of inertia
        it moves (tau = I alpha, Eq. 14, with the moment of inertia of Eq. 13; a neighbour
        held at its CM moves along instead, F = M a, Eq. 5), and a pin to the fixed frame,
        to a body that does not move or to a knot of loops holds it. The body's rating is
        the fastest: a chain under an even tension gives sqrt(T l / I), its zigzag; a light
        body between heavy ones rates their slow turn, as it only follows them. A body with
        two joints on closed loops of joints (a plank of a bridge anchored at both ends, a
        link of a ring) is rated as a chain's link: a path of k such bodies between two held
        ends keeps k - 2 of its 3 k freedoms (2 k + 2 pin rows), its zigzags. A knot of
        three or more joints on loops (:attr:`free_turn` 0: a grid's bodies) is not rated
        and holds its neighbours' turns there: each joint more takes two freedoms, and
        Box2D's joint grid hangs still, with 1e6 kg hung from it too, under loads that rate
        its knots, each on its own, up to h omega = 20. The loads are 2 lambda / h, lambda
        the last velocity stage's impulses (RATTLE's second half kick, h F / 2) without what
        the contact solve added (:meth:`take_extra`: a blow, not a held load). SHAKE takes
        the arms at the step's start (G(q0)), so that stiffness is explicit, and velocity
        Verlet grows the ring where h omega > 2: a light chain holding a heavy body rings
        there at steps that its own motion allows (issue 33). Each motion's stiffnesses over
        its moments of inertia is at most the largest of its turning bodies' own |k| / I, so
        the largest |k| / I of all (:data:`RATING_BOUND` above it for rounding) bounds the
        rating: a step that it does not halve, the rating does not halve either, and the
        bodies' modes are not rated then."""
        stiffness = [0.0] * len(self.bodies)
        warm, extra = self.warm, self.extra
        for i in self.pins:
            x, y = warm[i] - extra[i], warm[i + 1] - extra[i + 1]
            # r . F of each end: the x row's entry is (+-1, 0, -+r_y), the y row's
            # (0, +-1, +-r_x), the load on that end +-(x, y).
            for (b, _, _, turn_x), (_, _, _, turn_y) in zip(rows[i].entries,
                                                            rows[i + 1].entries):
                stiffness[b] += x * turn_y - y * turn_x
        if h > 0.0:
            bound = 2.0 * RATING_BOUND * max(abs(k) * free for k, free
                                             in zip(stiffness, self.free_turn)) / self.step_h
            if h * h * bound <= MAX_RING * MAX_RING:
                return bound
        inverse = self.inverse_mass
        most = 0.0
        for b, pins in enumerate(self.pinned):
            if self.free_turn[b] == 0.0 or inverse[3 * b] == 0.0:
                continue
            for pivot in range(-1, len(pins)):  # about its CM, then about each pin
                px, py = (0.0, 0.0) if pivot < 0 else pins[pivot][0]
                turn = stiffness[b]
                inertia = 1.0 / self.free_turn[b] + (px * px + py * py) / inverse[3 * b]
                for j, ((x, y), other, reach) in enumerate(pins):
                    if j == pivot:
                        continue
                    if other < 0 or inverse[3 * other] == 0.0 or self.free_turn[other] == 0.0:
                        break  # held: no turn about here
                    dx, dy = x - px, y - py
                    moved = dx * dx + dy * dy
                    if reach > 0.0:  # it turns along
                        share = moved / (reach * reach)
                        turn += stiffness[other] * share
                        inertia += share / self.free_turn[other]
                    else:  # it moves along
                        inertia += moved / inverse[3 * other]
                else:
                    most = max(most, turn / inertia)
        return 2.0 * most / self.step_h

    def ring(self, q: np.ndarray) -> float:
        """omega (rad/s) of :meth:`ringing` with the bodies at ``q`` (all bodies)."""
        return math.sqrt(self.ringing(self.rows(q[self.bodies].reshape(-1).tolist(),
                                                self.step_h)))

    def _count_turns(self, q: list[float]) -> None:
        """Keep counting whole turns of each joint angle from the pose ``q``."""
        for name, (a, b) in self.frames.items():
            pa, pb = a.place(q), b.place(q)
            self.angle[name] = self._joint_angle(name, pa, pb)
            self.raw[name] = pb[4] - pa[4]

    def _hold(self, rows0: list[JointRow], q: list[float], h: float) -> list[JointRow]:
        """Stage 1: move ``q`` along M^-1 G(q0)^T until the rigid rows have their values
        at the step's start (Newton's method on G(q) M^-1 G(q0)^T, which is not
        symmetric: factored by :func:`.sparse.lu`), warm-started from the last step's
        multipliers scaled to this step's length (they grow as h^2), and where that start
        fails and began further from the solution than the free step, once more from the
        free step (zero multipliers: a light body between heavy ones moves by the small
        difference of their large multipliers, which the last step's, along rows that have
        turned since, miss by far); returns the rows at the new ``q``. The matrix of one
        iterate serves the next ones while each cuts the error by :data:`CHORD` at least
        (near the solution the matrix changes by less than the error: a simplified Newton
        step costs a solve, not a factorization).
        Raises :class:`JointsUnsolved`, changing nothing but ``q``, when a step with its
        iterate's own matrix does not halve the largest error (SHAKE's equations have no
        solution near the step's end: a body turned far, or a long chain's weakest modes
        moved more than the directions at q0 can follow) or when the solution turns a
        body by more than :data:`MAX_TURN`."""
        self._near = None
        if not self.rigid:
            return self.rows(q, h)
        rigid = [rows0[i] for i in self.rigid]
        direction = directions(rigid, self.inverse_mass)
        target = [row.c for row in rigid]
        moved = list(q)
        if self.newton is not None:
            scale = h / self.step_h
            scale = scale * scale
            try:
                return self._newton(q, moved, direction, target, [x * scale for x in self.newton],
                                    h)
            except JointsUnsolved:
                q[:] = moved
                rows = self.rows(q, h)
                if not max(abs(rows[i].c - c0) for i, c0 in zip(self.rigid, target)
                           ) < self.first_error:
                    raise
        return self._newton(q, moved, direction, target, [0.0] * len(rigid), h)

    def _newton(self, q: list[float], moved: list[float], direction: Directions,
                target: list[float], nu: list[float], h: float) -> list[JointRow]:
        """:meth:`_hold`'s Newton iteration from the multipliers ``nu``, on ``q`` (which
        was ``moved``) towards the rigid rows' values ``target``; keeps the largest error
        of its first iterate in :attr:`first_error`."""
        apply(q, direction, nu)
        # The rows' values round at about eps |q|: no error can be asked below that.
        tolerance = max(self.tolerance, ROUNDING * (1.0 + max(map(abs, q))))
        pattern = self.rigid_pattern
        previous = math.inf
        factors: Optional[tuple[Factors, list[float]]] = None  # the last matrix's L U
        fresh = False  # whether the last step's matrix was that iterate's own
        for iteration in range(NEWTON_ITERATIONS):
            rows = self.rows(q, h)
            error = [rows[i].c - c0 for i, c0 in zip(self.rigid, target)]
            largest = max(map(abs, error))
            if iteration == 0:
                self.first_error = largest
            if largest <= tolerance:
                turned = max(abs(q[k] - moved[k]) for k in range(2, len(q), 3))
                if turned > self.max_turn:
                    raise JointsUnsolved(f"the joints turn a body by {turned:.3g} rad in a "
                                         f"step of {h:g} s")
                self.newton = nu
                self._near = factors
                return rows
            if fresh and not largest <= 0.5 * previous:
                raise JointsUnsolved(f"Newton's method on the joints stalls at {largest:.3g} "
                                     f"in a step of {h:g} s")
            fresh = factors is None or not largest <= CHORD * previous
            if fresh:
                upper = [0.0] * pattern.slots()
                diagonal, lower = matrix(pattern, [rows[i] for i in self.rigid], direction,
                                          upper=upper)
                factors = (lu(pattern, diagonal, lower, upper), upper)
            assert factors is not None
            previous = largest
            step = lu_solve(pattern, factors[0], factors[1], [-e for e in error])
            nu = [a + b for a, b in zip(nu, step)]
            apply(q, direction, step)
        raise JointsUnsolved(f"Newton's method on the joints did not converge in "
                             f"{NEWTON_ITERATIONS} iterations in a step of {h:g} s")

    def _correct(self, rows: list[JointRow], q: list[float], h: float) -> list[JointRow]:
        """Stage 2: remove drift of the rigid rows and limits passed, positions only;
        returns the rows at the corrected ``q``."""
        pattern = self.pattern
        assert pattern is not None  # the start pose has fixed the rows
        for _ in range(DRIFT_ITERATIONS):
            if not any((r.kind == RIGID and abs(r.c) > self.tolerance)
                       or (r.kind == LIMIT and r.c < -self.tolerance) for r in rows):
                break
            active = [r.kind == RIGID or (r.kind == LIMIT and r.c < 0.0) for r in rows]
            self._near = None  # the positions move off the Newton matrix's (and C reuses it)
            direction = directions(rows, self.inverse_mass)
            diagonal, lower = matrix(pattern, rows, direction, active)
            shift = substitute(pattern, factor(pattern, diagonal, lower, active),
                               [-r.c if on else 0.0 for r, on in zip(rows, active)])
            apply(q, direction, shift)
            rows = self.rows(q, h)
        return rows

    def _velocities(self, rows: list[JointRow], v: list[float], h: float) -> None:
        """Stage 3: the impulses at the final positions (where :attr:`share`, refined on the
        Newton matrix's L U while that gets every row's rate within the tolerance over
        ``h``; else from K's own factors); changes ``v`` in place and keeps each row's
        impulse for warm starting and the joints' efforts."""
        pattern = self.pattern
        assert pattern is not None  # the start pose has fixed the rows
        direction = directions(rows, self.inverse_mass)
        diagonal, lower = matrix(pattern, rows, direction)
        b = [-rate(row, v) for row in rows]
        low_bound = [-math.inf] * len(rows)
        high_bound = [math.inf] * len(rows)
        for i, row in enumerate(rows):
            if row.kind == LIMIT:
                b[i] -= (0.0 if row.c < 0.0 else row.c) / h
                low_bound[i] = 0.0
            elif row.kind == MOTOR:
                b[i] += row.speed
                low_bound[i], high_bound[i] = -row.bound, row.bound
            elif row.kind == SOFT:
                scale = 1.0 / diagonal[i] if row.scaled else 1.0
                stiffness, damping = row.stiffness * scale, row.damping * scale
                compliance = stiffness * h + damping
                if compliance == 0.0:  # a spring of zero stiffness and damping holds nothing
                    low_bound[i] = high_bound[i] = 0.0
                    continue
                diagonal[i] += 1.0 / (h * compliance)
                b[i] -= stiffness * row.c / compliance
        impulse = None
        if self.share and self._near is not None:  # rigid rows alone: no bounds
            # What the rows still move along, times h, the next step's Newton removes: at
            # most the tolerance, and no less than the rates round to.
            residual = max(self.tolerance / h, ROUNDING * (1.0 + max(map(abs, b))))
            impulse = refine(pattern, diagonal, lower, b, self._near, residual)
        if impulse is None:
            impulse = solve(pattern, diagonal, lower, b, (low_bound, high_bound), self.warm)
        apply(v, direction, impulse)
        self.warm = impulse
        self.step_h = h
        self._last = (rows, direction)
        self._set_efforts()

    def contact_units(self) -> list[JointUnit]:
        """The velocity rows of the last step's joint pass as units of the contact solve
        (:mod:`.coupled`): every row but the soft ones, on the scene's body indices, with
        the bounds left by the impulses this pass gave them."""
        if self._compiled:
            raise RuntimeError("the joint pass runs in the kernel: its rows are the kernel's")
        rows, direction = self._last
        index = self.bodies.tolist()
        h = self.step_h
        units = []
        for slot, (row, towards, x) in enumerate(zip(rows, direction, self.warm)):
            if row.kind == SOFT:
                continue
            target, lower, upper = 0.0, -math.inf, math.inf
            if row.kind == LIMIT:
                target, lower = -(0.0 if row.c < 0.0 else row.c) / h, -x
            elif row.kind == MOTOR:
                target, lower, upper = row.speed, -row.bound - x, row.bound - x
            units.append(JointUnit(slot, [(index[b], jx, jy, jw) for b, jx, jy, jw in row.entries],
                                   [(index[b], dx, dy, dw) for b, dx, dy, dw in towards],
                                   1.0 / dot(row, towards), target, lower, upper,
                                   min(max(self.extra[slot], lower), upper)))
        return units

    def settled_velocities(self) -> dict[int, list[float]]:
        """Per body (the scene's index), its velocity before the last step's velocity
        stage, which the step's positions moved with: the contact pass moves a body by h
        times the change from it (a motor's kick that a contact stops did not move the
        body, so stopping it must not move the body back)."""
        v = self._settled
        return {int(b): v[3 * k: 3 * k + 3] for k, b in enumerate(self.bodies)}

    def take_extra(self, units: list[JointUnit]) -> None:
        """Add the extra impulses the contact solve gave ``units`` to this step's impulses
        (so to the efforts and to the next step's warm start), and keep them to warm-start
        the next contact solve; ``units`` the solve left out count as zero."""
        self._changing()
        self.extra = [0.0] * len(self.keys)
        for unit in units:
            if unit.extra != 0.0:
                self.warm[unit.slot] += unit.extra
                self.extra[unit.slot] = unit.extra
        self._set_efforts()

    def _set_efforts(self) -> None:
        """Each joint's effort: its motor, limit and spring impulses over the last step."""
        self.efforts = {}
        h = self.step_h
        for (joint, part), x in zip(self.keys, self.warm):
            sign = EFFORT_SIGNS.get(part)
            if sign is not None:
                self.efforts[joint] = self.efforts.get(joint, 0.0) + sign * x / h
