/* The binding of the joint pass (joint.h) for hecker_dynamics/contact/joints_kernel.py:
 * joints, joint_state and joints_resolve, each taking keyword arguments.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdlib.h>
#include <string.h>

#include "bind.h"
#include "joint.h"
#include "sparse.h"

static void hd_joints_destructor(PyObject *capsule)
{
    hd_joints_free(PyCapsule_GetPointer(capsule, HD_JOINTS_CAPSULE));
}

PyDoc_STRVAR(joints_doc,
"joints(bodies, inverse_mass, ints, reals, rows, pattern, rigid_pattern, turning,\n"
"       free_turn, tolerance, max_turn, *, substeps=0, hertz=0.0, damping_ratio=0.0,\n"
"       share=False) -> Joints\n\n"
"A scene's joint pass (joint.h): the model indices of the bodies it holds and their 1/m,\n"
"1/m, 1/I; per joint, in the order JointPass solves them, HD_JOINT_INTS ints and\n"
"HD_JOINT_REALS reals; ``rows``: the number of rows JointPass counts, which the kernel\n"
"checks against its own; the patterns of all rows and of the rigid rows (contact/sparse.py:\n"
"Pattern), each as (start, columns, dependent); the model indices of the bodies whose turning\n"
"JointPass.parts watches; per body, JointPass.free_turn (its 1/I, 0 where loops of joints\n"
"hold its turn: the bodies hd_ringing rates); the position stages' tolerance; the most an arm may turn in a\n"
"step (JointPass.max_turn); soft joints (soft_joint.c): ``substeps`` a step's sub-steps (0:\n"
"the exact pass), ``hertz`` (Hz) and ``damping_ratio`` their rows' softness (SoftJoints);\n"
"``share``: the velocity stage refines on the Newton matrix's L U (JointPass.share).");

/* A contact/sparse.py Pattern from (start, columns, dependent); -1 with an exception set. */
static int hd_read_pattern(PyObject *triple, hd_pattern *p)
{
    PyObject *start_object, *columns_object, *dependent_object;
    if (!PyArg_ParseTuple(triple, "OOO:pattern", &start_object, &columns_object,
                          &dependent_object))
        return -1;
    Py_ssize_t count, length;
    long *start = hd_read_array(start_object, "start", 'q', -1, &length);
    long *columns = start == NULL ? NULL
                    : hd_read_array(columns_object, "columns", 'q', -1, &count);
    double *dependent = columns == NULL ? NULL
                        : hd_read_array(dependent_object, "dependent", 'd', length - 1, NULL);
    if (dependent == NULL) {
        free(start);
        free(columns);
        return -1;
    }
    const long rows = (long)length - 1;
    int ok = rows >= 0 && start[0] == 0 && start[rows] == (long)count;
    for (long i = 0; ok && i < rows; ++i) {
        ok = start[i] <= start[i + 1];
        for (long k = start[i]; ok && k < start[i + 1]; ++k)
            ok = 0 <= columns[k] && columns[k] < i
                 && (k == start[i] || columns[k - 1] < columns[k]);
    }
    if (!ok) {
        free(start);
        free(columns);
        free(dependent);
        PyErr_SetString(PyExc_ValueError, "pattern: not a contact/sparse.py Pattern");
        return -1;
    }
    if (hd_pattern_init(p, rows, start, columns, dependent) < 0) {
        PyErr_NoMemory();
        return -1;
    }
    return 0;
}

static PyObject *hd_py_joints(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"bodies", "inverse_mass", "ints", "reals", "rows", "pattern",
                            "rigid_pattern", "turning", "free_turn", "tolerance", "max_turn",
                            "substeps", "hertz", "damping_ratio", "share", NULL};
    PyObject *o[4], *patterns[2], *turning_object, *free_turn_object;
    long rows, substeps = 0;
    double tolerance, max_turn, hertz = 0.0, damping_ratio = 0.0;
    int share = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOlOOOOdd|$lddp:joints", names, o, o + 1,
                                     o + 2, o + 3, &rows, patterns, patterns + 1,
                                     &turning_object, &free_turn_object, &tolerance, &max_turn,
                                     &substeps, &hertz, &damping_ratio, &share))
        return NULL;
    if (substeps < 0) {
        PyErr_SetString(PyExc_ValueError, "joints: substeps must not be negative");
        return NULL;
    }
    hd_joint_model *m = calloc(1, sizeof(hd_joint_model));
    if (m == NULL)
        return PyErr_NoMemory();
    Py_ssize_t bodies, ints_count, turning;
    long *ints = NULL;
    double *reals = NULL;
    if ((m->bodies = hd_read_array(o[0], "bodies", 'q', -1, &bodies)) == NULL ||
        (m->inverse_mass = hd_read_array(o[1], "inverse_mass", 'd', 3 * bodies, NULL)) == NULL ||
        (m->free_turn = hd_read_array(free_turn_object, "free_turn", 'd', bodies, NULL)) == NULL ||
        (ints = hd_read_array(o[2], "ints", 'q', -1, &ints_count)) == NULL ||
        (reals = hd_read_array(o[3], "reals", 'd', ints_count / HD_JOINT_INTS * HD_JOINT_REALS,
                               NULL)) == NULL ||
        (m->turning = hd_read_array(turning_object, "turning", 'q', -1, &turning)) == NULL)
        goto fail;
    m->body_count = (long)bodies;
    m->turning_count = (long)turning;
    m->tolerance = tolerance, m->max_turn = max_turn, m->share = share;
    m->substeps = substeps, m->hertz = hertz, m->damping_ratio = damping_ratio;
    m->joint_count = (long)(ints_count / HD_JOINT_INTS);
    if (ints_count % HD_JOINT_INTS || (m->joints = calloc((size_t)m->joint_count + 1,
                                                          sizeof(hd_joint))) == NULL) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "joints: ints not of the layout of joint.h");
        goto fail;
    }
    for (long i = 0; i < m->joint_count; ++i) {
        const long *n = ints + HD_JOINT_INTS * i;
        const double *r = reals + HD_JOINT_REALS * i;
        hd_joint *jt = m->joints + i;
        jt->kind = (int)n[0], jt->a = n[1], jt->b = n[2];
        jt->has_lower = n[3] != 0, jt->has_upper = n[4] != 0, jt->has_motor = n[5] != 0;
        jt->has_spring = n[6] != 0, jt->gear_a = n[7], jt->gear_b = n[8];
        int ok = jt->kind >= HD_REVOLUTE && jt->kind <= HD_GEAR;
        if (jt->kind == HD_GEAR)
            ok = ok && 0 <= n[7] && n[7] < m->joint_count && 0 <= n[8] && n[8] < m->joint_count
                 && ints[HD_JOINT_INTS * n[7]] == HD_REVOLUTE
                 && ints[HD_JOINT_INTS * n[8]] == HD_REVOLUTE;
        else
            ok = ok && -1 <= jt->a && jt->a < m->body_count && 0 <= jt->b && jt->b < m->body_count;
        if (!ok) {
            PyErr_Format(PyExc_ValueError, "joint %ld: not the layout of joint.h", i);
            goto fail;
        }
        memcpy(jt->point_a, r, 2 * sizeof(double));
        memcpy(jt->point_b, r + 2, 2 * sizeof(double));
        memcpy(jt->axis, r + 4, 2 * sizeof(double));
        jt->lower = r[6], jt->upper = r[7], jt->max_effort = r[8], jt->stiffness = r[9];
        jt->damping = r[10], jt->rest = r[11], jt->length = r[12], jt->ratio = r[13];
    }
    for (Py_ssize_t k = 0; k < bodies; ++k)
        if (m->bodies[k] < 0) {
            PyErr_SetString(PyExc_ValueError, "joints: a negative body index");
            goto fail;
        }
    for (Py_ssize_t k = 0; k < turning; ++k)
        if (m->turning[k] < 0) {
            PyErr_SetString(PyExc_ValueError, "joints: a negative turning body");
            goto fail;
        }
    if (hd_read_pattern(patterns[0], &m->pattern) < 0 ||
            hd_read_pattern(patterns[1], &m->rigid_pattern) < 0)
        goto fail;
    const int status = hd_joints_prepare(m);
    if (status == HD_JOINTS_OUT_OF_MEMORY) {
        PyErr_NoMemory();
        goto fail;
    }
    if (status == HD_JOINTS_MISMATCH || m->row_count != rows || m->pattern.n != rows) {
        PyErr_Format(PyExc_ValueError, "joints: %ld rows (%ld rigid) in the kernel, %ld in "
                     "Python", m->row_count, m->rigid_count, rows);
        goto fail;
    }
    free(ints);
    free(reals);
    PyObject *capsule = PyCapsule_New(m, HD_JOINTS_CAPSULE, hd_joints_destructor);
    if (capsule == NULL)
        hd_joints_free(m);
    return capsule;
fail:
    free(ints);
    free(reals);
    hd_joints_free(m);
    return NULL;
}

/* The state's length: HD_JOINT_STATE per joint, the warm starts, the Newton multipliers,
 * the contact solve's extra impulses, whether the multipliers are set, and the last
 * step's length. */
static Py_ssize_t hd_joint_state_length(const hd_joint_model *m)
{
    return HD_JOINT_STATE * m->joint_count + 2 * m->row_count + m->rigid_count + 4;
}

PyDoc_STRVAR(joint_state_doc,
"joint_state(joints, state, load)\n\n"
"Copy the joint pass ``joints`` (joints())'s state from ``state`` into the kernel if\n"
"``load`` is true, else from the kernel into ``state``: ``state`` C-contiguous float64,\n"
"HD_JOINT_STATE values per joint (reference angle (rad), reference distance along the axis\n"
"(m), angle (rad), its unwrapped value (rad), motor speed (rad/s or m/s)), the warm-start\n"
"impulses of the rows, the Newton multipliers of the rigid rows, the contact solve's extra\n"
"impulses of the rows, 1.0 if the multipliers are set, the last step's length (s).");

static PyObject *hd_py_joint_state(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                                   PyObject *kwnames)
{
    static const char *const names[] = {"joints", "state", "load", NULL};
    PyObject *given[3];
    hd_joint_model *m = hd_capsule_arguments("joint_state", args, nargs, kwnames, names,
                                             3, 3, HD_JOINTS_CAPSULE, given);
    if (m == NULL)
        return NULL;
    const int load = PyObject_IsTrue(given[2]);
    Py_buffer view;
    if (load < 0
        || hd_get_buffer(given[1], &view, "state", 'd', hd_joint_state_length(m), !load) < 0)
        return NULL;
    double *s = view.buf;
    for (long i = 0; i < m->joint_count; ++i, s += HD_JOINT_STATE) {
        hd_joint *jt = m->joints + i;
        double *fields[HD_JOINT_STATE] = {&jt->reference_angle, &jt->reference_along,
                                          &jt->angle, &jt->raw, &jt->motor_speed};
        for (int k = 0; k < HD_JOINT_STATE; ++k) {
            if (load)
                *fields[k] = s[k];
            else
                s[k] = *fields[k];
        }
    }
    const size_t warm = (size_t)m->row_count * sizeof(double),
                 newton = (size_t)m->rigid_count * sizeof(double);
    const long flags = 2 * m->row_count + m->rigid_count;
    if (load) {
        m->ended = 0;  /* its state may differ: build the next pass's rows afresh */
        memcpy(m->warm, s, warm);
        memcpy(m->newton, s + m->row_count, newton);
        memcpy(m->extra, s + m->row_count + m->rigid_count, warm);
        m->newton_valid = s[flags] != 0.0;
        m->last_h = s[flags + 1];
        m->remembered = (long)s[flags + 2], m->settled_steps = (long)s[flags + 3];
        m->needed = 1;
    } else {
        memcpy(s, m->warm, warm);
        memcpy(s + m->row_count, m->newton, newton);
        memcpy(s + m->row_count + m->rigid_count, m->extra, warm);
        s[flags] = m->newton_valid ? 1.0 : 0.0;
        s[flags + 1] = m->last_h;
        s[flags + 2] = (double)m->remembered, s[flags + 3] = (double)m->settled_steps;
    }
    PyBuffer_Release(&view);
    Py_RETURN_NONE;
}

PyDoc_STRVAR(joints_resolve_doc,
"joints_resolve(joints, bodies, q0, q1, v1, h) -> bool\n\n"
"The joint pass ``joints`` (joints()) after a step of ``h`` (s) from q0 to (q1, v1)\n"
"(JointPass.resolve; a soft pass's sub-step, SoftJointPass.resolve): ``bodies`` the model's number of bodies; ``q0`` the step's start and\n"
"``q1`` its end, (x, y, angle) of each CM, ``v1`` the end's (vx, vy, omega), each\n"
"C-contiguous float64 of 3 * bodies values; q1 and v1 are updated in place. Returns False,\n"
"changing nothing, when the positions have no solution near the step's end\n"
"(JointsUnsolved), else True.");

static PyObject *hd_py_joints_resolve(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                                      PyObject *kwnames)
{
    static const char *const names[] = {"joints", "bodies", "q0", "q1", "v1", "h", NULL};
    PyObject *given[6];
    hd_joint_model *m = hd_capsule_arguments("joints_resolve", args, nargs, kwnames, names,
                                             6, 6, HD_JOINTS_CAPSULE, given);
    if (m == NULL)
        return NULL;
    PyObject *const *objects = given + 2;
    const long bodies = PyLong_AsLong(given[1]);
    if (bodies == -1 && PyErr_Occurred())
        return NULL;
    const double h = PyFloat_AsDouble(given[5]);
    if (h == -1.0 && PyErr_Occurred())
        return NULL;
    for (long k = 0; k < m->body_count; ++k)
        if (m->bodies[k] >= bodies) {
            PyErr_SetString(PyExc_ValueError, "joints_resolve: a joint's body out of range");
            return NULL;
        }
    Py_buffer views[3];
    for (int k = 0; k < 3; ++k) {
        if (hd_get_buffer(objects[k], views + k, names[k + 2], 'd', 3 * bodies, k > 0) < 0) {
            while (k-- > 0)
                PyBuffer_Release(views + k);
            return NULL;
        }
    }
    int status;
    Py_BEGIN_ALLOW_THREADS
    if (m->substeps > 0) {
        hd_soft_joints_resolve(m, views[0].buf, views[1].buf, views[2].buf, h);
        status = HD_JOINTS_OK;
    } else {
        status = hd_joints_resolve(m, views[0].buf, views[1].buf, views[2].buf, h);
    }
    Py_END_ALLOW_THREADS
    for (int k = 0; k < 3; ++k)
        PyBuffer_Release(views + k);
    if (status == HD_JOINTS_OUT_OF_MEMORY)
        return PyErr_NoMemory();
    return PyBool_FromLong(status == HD_JOINTS_OK);
}

PyMethodDef hd_bind_joints[] = {
    {"joints", (PyCFunction)(void (*)(void))hd_py_joints, METH_VARARGS | METH_KEYWORDS,
     joints_doc},
    {"joint_state", (PyCFunction)(void (*)(void))hd_py_joint_state,
     METH_FASTCALL | METH_KEYWORDS, joint_state_doc},
    {"joints_resolve", (PyCFunction)(void (*)(void))hd_py_joints_resolve,
     METH_FASTCALL | METH_KEYWORDS, joints_resolve_doc},
    {NULL, NULL, 0, NULL},
};
