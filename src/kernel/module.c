/* hecker_dynamics._kernel: the Python binding of the compiled kernel.
 *
 * Arrays cross by the buffer protocol only (C-contiguous doubles and 64-bit integers), so
 * the module does not depend on numpy's C API or its version. Its callers:
 * hecker_dynamics/dynamics/kernel.py (the force terms in the layout of kernel.h, the
 * steppers, the energy bound), contact/compiled.py (the contact pass of contact.h) and
 * contact/joints_kernel.py (the joint pass of joint.h) and sensors/laser.py (the laser
 * ray casts of raycast.h).
 *
 * One binding file per Python bridge (bind_forces.c, bind_stepper.c, bind_contacts.c,
 * bind_joints.c, bind_raycast.c, sharing bind.c); this file makes the module and its constants.
 */
#include "bind.h"
#include "contact.h"
#include "drive.h"
#include "joint.h"
#include "kernel.h"
#include "wide.h"

static struct PyModuleDef hd_module = {
    PyModuleDef_HEAD_INIT, "_kernel",
    "The compiled kernel of hecker_dynamics (see hecker_dynamics.dynamics.kernel).", -1, NULL,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__kernel(void)
{
    /* The codes of kernel.h, so that the Python side never writes them again. */
    static const struct { const char *name; long value; } constants[] = {
        {"GRAVITY", HD_GRAVITY}, {"ANCHOR_SPRING", HD_ANCHOR_SPRING},
        {"BODY_SPRING", HD_BODY_SPRING},
        {"CENTER_DRAG", HD_CENTER_DRAG}, {"POINT_DRAG", HD_POINT_DRAG},
        {"ANGULAR_DAMPING", HD_ANGULAR_DAMPING}, {"WRENCH", HD_WRENCH},
        {"EXPLICIT_EULER", HD_EXPLICIT_EULER}, {"SEMI_IMPLICIT_EULER", HD_SEMI_IMPLICIT_EULER},
        {"VELOCITY_VERLET", HD_VELOCITY_VERLET}, {"RK4", HD_RK4}, {"EMBEDDED", HD_EMBEDDED},
        {"ADVANCED", HD_ADVANCED}, {"NOT_FINITE", HD_NOT_FINITE},
        {"SUBSTEP_UNDERFLOW", HD_SUBSTEP_UNDERFLOW}, {"TOO_MANY_SUBSTEPS", HD_TOO_MANY_SUBSTEPS},
        {"MAX_SUBSTEPS", HD_MAX_PAIR_SUBSTEPS}, {"CIRCLE", HD_CIRCLE}, {"POLYGON", HD_POLYGON},
        {"OUTLINE", HD_OUTLINE}, {"MAX_ITERATIONS", HD_MAX_ITERATIONS},
        {"MIN_ITERATIONS", HD_MIN_ITERATIONS}, {"WORK", HD_WORK}, {"SETTLE", HD_SETTLE},
        {"WIDE_UNITS", HD_WIDE_UNITS}, {"COLOURS", HD_COLOURS},
        {"POSITION_ITERATIONS", HD_POSITION_ITERATIONS}, {"MAX_CONTACT_SUBSTEPS", HD_MAX_SUBSTEPS},
        {"JOINTS_UNSOLVED", HD_UNSOLVED_JOINTS}, {"JOINT_NEWTON_ITERATIONS", HD_NEWTON_ITERATIONS},
        {"JOINT_MOST_SUBSTEPS", HD_MOST_SUBSTEPS}, {"JOINT_SETTLED_STEPS", HD_SETTLED_STEPS},
        {"JOINT_DRIFT_ITERATIONS", HD_DRIFT_ITERATIONS},
        {"JOINT_ACTIVE_SETS", HD_ACTIVE_SETS}, {"JOINT_REFINEMENTS", HD_REFINEMENTS},
        {"JOINT_MAX_ITERATIONS", HD_JOINT_MAX_ITERATIONS}, {"JOINT_INTS", HD_JOINT_INTS},
        {"JOINT_REALS", HD_JOINT_REALS}, {"JOINT_STATE", HD_JOINT_STATE},
        {"REVOLUTE", HD_REVOLUTE}, {"PRISMATIC", HD_PRISMATIC}, {"WELD", HD_WELD},
        {"ROD", HD_ROD}, {"ROPE", HD_ROPE}, {"GEAR", HD_GEAR},
        {"DRIVE_INTS", HD_DRIVE_INTS}, {"DRIVE_REALS", HD_DRIVE_REALS},
        {"DRIVE_MOST", HD_DRIVE_MOST},
    };
    PyObject *m = PyModule_Create(&hd_module);
    if (m == NULL)
        return NULL;
    if (PyModule_AddFunctions(m, hd_bind_forces) < 0
        || PyModule_AddFunctions(m, hd_bind_stepper) < 0
        || PyModule_AddFunctions(m, hd_bind_contacts) < 0
        || PyModule_AddFunctions(m, hd_bind_joints) < 0
        || PyModule_AddFunctions(m, hd_bind_raycast) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    for (size_t k = 0; k < sizeof constants / sizeof constants[0]; ++k) {
        if (PyModule_AddIntConstant(m, constants[k].name, constants[k].value) < 0) {
            Py_DECREF(m);
            return NULL;
        }
    }
    /* The contact pass's tolerances, which test/contact/test_compiled.py checks against
     * the Python modules'. */
    static const struct { const char *name; double value; } reals[] = {
        {"CONVERGED", HD_CONVERGED}, {"MARGIN", HD_MARGIN}, {"MATCH", HD_MATCH},
        {"FRICTION_CARRY", HD_FRICTION_CARRY},
        {"SLOP", HD_SLOP}, {"CORRECTION", HD_CORRECTION}, {"MAX_CORRECTION", HD_MAX_CORRECTION},
        {"JOINT_TOLERANCE", HD_JOINT_TOLERANCE}, {"JOINT_CONVERGED", HD_JOINT_CONVERGED},
        {"JOINT_ROUNDING", HD_JOINT_ROUNDING}, {"JOINT_MAX_TURN", HD_MAX_TURN},
        {"JOINT_MAX_RING", HD_MAX_RING}, {"JOINT_RATING_BOUND", HD_RATING_BOUND},
        {"JOINT_CHORD", HD_CHORD},
        {"JOINT_DEPENDENT", HD_DEPENDENT},
        {"MAX_CONDITION", HD_MAX_CONDITION}, {"SLEEP_SPEED", HD_SLEEP_SPEED},
        {"TIME_TO_SLEEP", HD_TIME_TO_SLEEP},
    };
    for (size_t k = 0; k < sizeof reals / sizeof reals[0]; ++k) {
        PyObject *value = PyFloat_FromDouble(reals[k].value);
        if (value == NULL || PyModule_AddObject(m, reals[k].name, value) < 0) {
            Py_XDECREF(value);
            Py_DECREF(m);
            return NULL;
        }
    }
    return m;
}
