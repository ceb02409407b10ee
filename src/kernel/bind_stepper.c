/* The binding of whole steps (steppers.c) for hecker_dynamics/dynamics/kernel.py:
 * stepper, step, failed_state.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdlib.h>
#include <string.h>

#include "bind.h"
#include "contact.h"
#include "joint.h"
#include "kernel.h"

/* A stepper capsule's contents: the kernel's stepper and the objects whose data it points
 * into, held for its lifetime. */
typedef struct {
    hd_stepper stepper;
    PyObject *program, *pair, *contacts;
} hd_stepper_capsule;

static void hd_stepper_destructor(PyObject *capsule)
{
    hd_stepper_capsule *c = PyCapsule_GetPointer(capsule, HD_STEPPER_CAPSULE);
    if (c == NULL)
        return;
    hd_stepper_free(&c->stepper);
    Py_XDECREF(c->program);
    Py_XDECREF(c->pair);
    Py_XDECREF(c->contacts);
    free(c);
}

PyDoc_STRVAR(stepper_doc,
"stepper(program, method, pair, tolerance, contacts) -> Stepper\n\n"
"Whole steps of ``method`` (EXPLICIT_EULER, SEMI_IMPLICIT_EULER, VELOCITY_VERLET, RK4, or\n"
"EMBEDDED with the Pair ``pair`` and ``tolerance``) on ``program``, with the contact pass\n"
"``contacts`` (None: none) after each step, and the memory they need, for ``step``.");

static PyObject *hd_py_stepper(PyObject *self, PyObject *args)
{
    PyObject *program, *pair_object, *contacts_object;
    int method;
    double tolerance;
    hd_program *p, *unused;
    hd_pair *pair = NULL;
    hd_contact_model *contacts = NULL;
    if (!PyArg_ParseTuple(args, "OiOdO:stepper", &program, &method, &pair_object, &tolerance,
                          &contacts_object) ||
        hd_get_programs(program, Py_None, &p, &unused) < 0)
        return NULL;
    if (method < HD_EXPLICIT_EULER || method > HD_EMBEDDED) {
        PyErr_Format(PyExc_ValueError, "unknown method %d", method);
        return NULL;
    }
    if (method == HD_EMBEDDED
        && (pair = PyCapsule_GetPointer(pair_object, HD_PAIR_CAPSULE)) == NULL)
        return NULL;
    if (contacts_object != Py_None) {
        if ((contacts = PyCapsule_GetPointer(contacts_object, HD_CONTACTS_CAPSULE)) == NULL)
            return NULL;
        if (contacts->bodies != p->bodies) {
            PyErr_SetString(PyExc_ValueError, "contacts: a contact pass for other bodies");
            return NULL;
        }
    }
    hd_stepper_capsule *c = calloc(1, sizeof(hd_stepper_capsule));
    if (c == NULL)
        return PyErr_NoMemory();
    if (hd_stepper_init(&c->stepper, p, method, pair, tolerance, contacts) != HD_ADVANCED) {
        free(c);
        return PyErr_NoMemory();
    }
    PyObject *capsule = PyCapsule_New(c, HD_STEPPER_CAPSULE, hd_stepper_destructor);
    if (capsule == NULL) {
        hd_stepper_free(&c->stepper);
        free(c);
        return NULL;
    }
    c->program = Py_NewRef(program);
    c->pair = Py_NewRef(pair_object);
    c->contacts = Py_NewRef(contacts_object);
    return capsule;
}

/* Body-steps of work below which a call keeps the GIL: releasing and taking it back costs
 * more than such a call's steps. */
#define HD_GIL_WORK 4096L

PyDoc_STRVAR(step_doc,
"step(stepper, inputs, oriented, q, v, h, steps, size, joints)\n"
"    -> (status, taken, evaluations, substeps, rejected, size)\n\n"
"Advance (q, v), C-contiguous float64 arrays of 3 values per body, in place by up to\n"
"``steps`` steps of ``h`` with the Stepper's method and passes, the inputs' program\n"
"``inputs`` (None: none) added to its forces (an embedded pair starting from sub-step\n"
"``size``), wrapping the angles after each step. ``oriented``: some active force needs the\n"
"angles; ``joints`` (None: none): the joint pass before the contacts. ``status``: ADVANCED,\n"
"NOT_FINITE (a new state was not finite; ``failed_state`` gives it), SUBSTEP_UNDERFLOW,\n"
"TOO_MANY_SUBSTEPS or JOINTS_UNSOLVED. The GIL is released meanwhile, unless the call is\n"
"short.");

static PyObject *hd_py_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 9) {
        PyErr_Format(PyExc_TypeError, "step() takes 9 arguments (%zd given)", nargs);
        return NULL;
    }
    hd_stepper_capsule *c = PyCapsule_GetPointer(args[0], HD_STEPPER_CAPSULE);
    if (c == NULL)
        return NULL;
    hd_stepper *s = &c->stepper;
    hd_program *in = NULL;
    if (args[1] != Py_None) {
        if ((in = PyCapsule_GetPointer(args[1], HD_PROGRAM_CAPSULE)) == NULL)
            return NULL;
        if (in->bodies != s->program->bodies) {
            PyErr_SetString(PyExc_ValueError, "inputs: a program for other bodies");
            return NULL;
        }
    }
    const int oriented = PyObject_IsTrue(args[2]);
    const double h = PyFloat_AsDouble(args[5]);
    const long steps = PyLong_AsLong(args[6]);
    double size = PyFloat_AsDouble(args[7]);
    if (oriented < 0 || PyErr_Occurred())
        return NULL;
    hd_joint_model *joints = NULL;
    if (args[8] != Py_None) {
        if ((joints = PyCapsule_GetPointer(args[8], HD_JOINTS_CAPSULE)) == NULL)
            return NULL;
        for (long k = 0; k < joints->body_count; ++k)
            if (joints->bodies[k] >= s->program->bodies) {
                PyErr_SetString(PyExc_ValueError, "joints: a joint pass for other bodies");
                return NULL;
            }
    }
    if (s->method != HD_EMBEDDED)
        size = 0.0;
    Py_buffer qv, vv;
    if (hd_get_state(args[3], args[4], 3 * s->program->bodies, &qv, &vv) < 0)
        return NULL;
    long taken = 0;
    hd_work work = {0, 0, 0};
    int status;
    if (steps * s->program->bodies < HD_GIL_WORK && s->contacts == NULL && joints == NULL) {
        status = hd_stepper_advance(s, in, oriented, joints, &size, qv.buf, vv.buf, h, steps,
                                    &taken, &work);
    } else {
        Py_BEGIN_ALLOW_THREADS
        status = hd_stepper_advance(s, in, oriented, joints, &size, qv.buf, vv.buf, h, steps,
                                    &taken, &work);
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&qv);
    PyBuffer_Release(&vv);
    if (status == HD_OUT_OF_MEMORY)
        return PyErr_NoMemory();
    return Py_BuildValue("illlld", status, taken, work.evaluations, work.substeps,
                         work.rejected, size);
}

PyDoc_STRVAR(failed_state_doc,
"failed_state(stepper, q, v)\n\n"
"Copy the state that ended the last ``step`` with NOT_FINITE into (q, v).");

static PyObject *hd_py_failed_state(PyObject *self, PyObject *args)
{
    PyObject *capsule, *qo, *vo;
    if (!PyArg_ParseTuple(args, "OOO:failed_state", &capsule, &qo, &vo))
        return NULL;
    hd_stepper_capsule *c = PyCapsule_GetPointer(capsule, HD_STEPPER_CAPSULE);
    if (c == NULL)
        return NULL;
    const Py_ssize_t n3 = 3 * c->stepper.program->bodies;
    Py_buffer qv, vv;
    if (hd_get_state(qo, vo, n3, &qv, &vv) < 0)
        return NULL;
    memcpy(qv.buf, c->stepper.q_new, (size_t)n3 * sizeof(double));
    memcpy(vv.buf, c->stepper.v_new, (size_t)n3 * sizeof(double));
    PyBuffer_Release(&qv);
    PyBuffer_Release(&vv);
    Py_RETURN_NONE;
}


PyMethodDef hd_bind_stepper[] = {
    {"stepper", hd_py_stepper, METH_VARARGS, stepper_doc},
    {"step", (PyCFunction)(void (*)(void))hd_py_step, METH_FASTCALL, step_doc},
    {"failed_state", hd_py_failed_state, METH_VARARGS, failed_state_doc},
    {NULL, NULL, 0, NULL},
};
