/* hecker_dynamics._kernel: the Python binding of the compiled kernel.
 *
 * Arrays cross by the buffer protocol only (C-contiguous doubles and 64-bit integers), so
 * the module does not depend on numpy's C API or its version. Its callers:
 * hecker_dynamics/dynamics/kernel.py (the force terms in the layout of kernel.h, the
 * steppers, the energy bound), contact/compiled.py (the contact pass of contact.h) and
 * contact/joints_kernel.py (the joint pass of joint.h).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdlib.h>
#include <string.h>

#include "contact.h"
#include "coupled.h"
#include "joint.h"
#include "kernel.h"
#include "wide.h"

static const char *PROGRAM = "hecker_dynamics._kernel.Program";
static const char *PAIR = "hecker_dynamics._kernel.Pair";
static const char *CONTACTS = "hecker_dynamics._kernel.Contacts";
static const char *JOINTS = "hecker_dynamics._kernel.Joints";
static const char *STEPPER = "hecker_dynamics._kernel.Stepper";

/* A C-contiguous buffer of `count` items of `format` ("d" or an 8-byte integer), or -1 with
 * an exception set. `count` < 0: any length, returned in view->len / itemsize. */
static int hd_get_buffer(PyObject *object, Py_buffer *view, const char *what, char format,
                         Py_ssize_t count, int writable)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(object, view, flags) < 0)
        return -1;
    const char *f = view->format ? view->format : "B";
    if (*f == '<' || *f == '=' || *f == '@')
        ++f;
    int ok = view->itemsize == 8 && f[0] != '\0' && f[1] == '\0' &&
             (format == 'd' ? f[0] == 'd' : (f[0] == 'q' || f[0] == 'l'));
    if (!ok) {
        PyErr_Format(PyExc_TypeError, "%s: expected %s of 8 bytes, got format '%s'", what,
                     format == 'd' ? "float64" : "int64", view->format ? view->format : "B");
    } else if (count >= 0 && view->len != count * 8) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd values, got %zd", what, count,
                     view->len / 8);
        ok = 0;
    }
    if (!ok) {
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

static void hd_free_program(hd_program *p)
{
    if (p == NULL)
        return;
    for (long t = 0; t < p->term_count; ++t) {
        free(p->terms[t].ints);
        free(p->terms[t].reals);
    }
    free(p->terms);
    free(p->inverse_mass);
    free(p);
}

static void hd_program_destructor(PyObject *capsule)
{
    hd_free_program(PyCapsule_GetPointer(capsule, PROGRAM));
}

static void *hd_copy_of(const Py_buffer *view)
{
    void *copy = malloc(view->len > 0 ? (size_t)view->len : 1);
    if (copy != NULL && view->len > 0)
        memcpy(copy, view->buf, (size_t)view->len);
    return copy;
}

/* Check the body indices of a term: targets in [0, N), axes and point owners in [-1, N). */
static int hd_check_bodies(const hd_term *t, long bodies)
{
    const int ni = hd_int_columns(t->kind);
    for (long e = 0; e < t->count; ++e) {
        const long *i = t->ints + ni * e;
        int ok = i[0] >= 0 && i[0] < bodies;
        if (t->kind == HD_BODY_SPRING)
            ok = ok && i[1] >= 0 && i[1] < bodies;
        if (t->kind == HD_WRENCH)
            ok = ok && i[1] >= -1 && i[1] < bodies && i[2] >= -1 && i[2] < bodies;
        if (!ok) {
            PyErr_Format(PyExc_ValueError, "term of kind %d, instance %ld: a body index is "
                         "out of range for %ld bodies", t->kind, e, bodies);
            return -1;
        }
    }
    return 0;
}

static int hd_read_term(PyObject *item, hd_term *term, long bodies)
{
    PyObject *ints, *reals;
    if (!PyTuple_Check(item)) {  /* PyArg_ParseTuple would raise SystemError */
        PyErr_Format(PyExc_TypeError, "a term is (kind, ints, reals), not %.100s",
                     Py_TYPE(item)->tp_name);
        return -1;
    }
    if (!PyArg_ParseTuple(item, "iOO;a term is (kind, ints, reals)", &term->kind, &ints,
                          &reals))
        return -1;
    const int ni = hd_int_columns(term->kind), nr = hd_real_columns(term->kind);
    if (ni == 0) {
        PyErr_Format(PyExc_ValueError, "unknown term kind %d", term->kind);
        return -1;
    }
    Py_buffer iv, rv;
    if (hd_get_buffer(ints, &iv, "term ints", 'q', -1, 0) < 0)
        return -1;
    term->count = (long)(iv.len / 8 / ni);
    if (iv.len != (Py_ssize_t)term->count * ni * 8 ||
        hd_get_buffer(reals, &rv, "term reals", 'd', (Py_ssize_t)term->count * nr, 0) < 0) {
        if (!PyErr_Occurred())
            PyErr_Format(PyExc_ValueError, "term of kind %d: %zd ints is not a whole number "
                         "of rows of %d", term->kind, iv.len / 8, ni);
        PyBuffer_Release(&iv);
        return -1;
    }
    term->ints = hd_copy_of(&iv);
    term->reals = hd_copy_of(&rv);
    PyBuffer_Release(&iv);
    PyBuffer_Release(&rv);
    if (term->ints == NULL || term->reals == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    return hd_check_bodies(term, bodies);
}

PyDoc_STRVAR(program_doc,
"program(bodies, inverse_mass, terms) -> capsule\n\n"
"Copy a model's force terms into a program: ``inverse_mass`` holds 1/m, 1/m, 1/I per body\n"
"(None for a program of inputs), ``terms`` is a sequence of (kind, ints, reals) with the\n"
"columns of kernel.h per instance, in the order they are summed.");

static PyObject *hd_py_program(PyObject *self, PyObject *args)
{
    long bodies;
    PyObject *inverse_mass, *terms;
    if (!PyArg_ParseTuple(args, "lOO:program", &bodies, &inverse_mass, &terms))
        return NULL;
    if (bodies < 0) {
        PyErr_SetString(PyExc_ValueError, "bodies must not be negative");
        return NULL;
    }
    /* The lengths 3 N (and the scratch and stage buffers, a few dozen doubles per body)
     * are computed in Py_ssize_t and size_t: beyond this they would wrap around, and a
     * wrapped, negative 3 N would turn off the length checks of get_buffer. */
    if (bodies > PY_SSIZE_T_MAX / 1024) {
        PyErr_Format(PyExc_ValueError, "too many bodies: %ld", bodies);
        return NULL;
    }
    /* A tuple of our own: a term's __index__ cannot then change what is being read. */
    PyObject *sequence = PySequence_Tuple(terms);
    if (sequence == NULL)
        return NULL;
    hd_program *p = calloc(1, sizeof(hd_program));
    Py_ssize_t count = PyTuple_GET_SIZE(sequence);
    if (p == NULL || (p->terms = calloc(count > 0 ? (size_t)count : 1, sizeof(hd_term))) == NULL) {
        free(p);
        Py_DECREF(sequence);
        return PyErr_NoMemory();
    }
    p->bodies = bodies;
    if (inverse_mass != Py_None) {
        Py_buffer view;
        if (hd_get_buffer(inverse_mass, &view, "inverse_mass", 'd', 3 * bodies, 0) < 0)
            goto fail;
        p->inverse_mass = hd_copy_of(&view);
        PyBuffer_Release(&view);
        if (p->inverse_mass == NULL) {
            PyErr_NoMemory();
            goto fail;
        }
    }
    for (Py_ssize_t t = 0; t < count; ++t) {
        p->term_count = (long)t + 1;  /* so that a failure frees what this term copied */
        if (hd_read_term(PyTuple_GET_ITEM(sequence, t), p->terms + t, bodies) < 0)
            goto fail;
    }
    Py_DECREF(sequence);
    PyObject *capsule = PyCapsule_New(p, PROGRAM, hd_program_destructor);
    if (capsule == NULL)
        hd_free_program(p);
    return capsule;
fail:
    Py_DECREF(sequence);
    hd_free_program(p);
    return NULL;
}

static void hd_free_pair(hd_pair *pair)
{
    if (pair != NULL) {
        free(pair->a);
        free(pair->error);
        free(pair);
    }
}

static void hd_pair_destructor(PyObject *capsule)
{
    hd_free_pair(PyCapsule_GetPointer(capsule, PAIR));
}

PyDoc_STRVAR(pair_doc,
"pair(slopes, a, error, error_order) -> capsule\n\n"
"An embedded Runge-Kutta pair: ``a`` is slopes x (slopes - 1) coefficients (stages, then\n"
"the weights of the new state), ``error`` rows of ``slopes`` coefficients each.");

static PyObject *hd_py_pair(PyObject *self, PyObject *args)
{
    long slopes;
    int error_order;
    PyObject *a, *error;
    if (!PyArg_ParseTuple(args, "lOOi:pair", &slopes, &a, &error, &error_order))
        return NULL;
    if (slopes < 2 || slopes > 64) {
        PyErr_SetString(PyExc_ValueError, "a pair has 2 to 64 slopes");
        return NULL;
    }
    Py_buffer av, ev;
    if (hd_get_buffer(a, &av, "a", 'd', slopes * (slopes - 1), 0) < 0)
        return NULL;
    if (hd_get_buffer(error, &ev, "error", 'd', -1, 0) < 0) {
        PyBuffer_Release(&av);
        return NULL;
    }
    long rows = (long)(ev.len / 8 / slopes);
    hd_pair *pair = calloc(1, sizeof(hd_pair));
    if (rows < 1 || rows > 2 || ev.len != (Py_ssize_t)rows * slopes * 8) {
        PyErr_SetString(PyExc_ValueError, "error must hold 1 or 2 rows of `slopes` values");
    } else if (pair != NULL) {
        pair->slopes = slopes;
        pair->error_rows = rows;
        pair->error_order = error_order;
        pair->a = hd_copy_of(&av);
        pair->error = hd_copy_of(&ev);
        for (long r = 0; pair->error != NULL && r < rows; ++r)
            pair->needs_new_state |= pair->error[r * slopes + slopes - 1] != 0.0;
    }
    PyBuffer_Release(&av);
    PyBuffer_Release(&ev);
    if (PyErr_Occurred() || pair == NULL || pair->a == NULL || pair->error == NULL) {
        hd_free_pair(pair);
        return PyErr_Occurred() ? NULL : PyErr_NoMemory();
    }
    PyObject *capsule = PyCapsule_New(pair, PAIR, hd_pair_destructor);
    if (capsule == NULL)
        hd_free_pair(pair);
    return capsule;
}

/* The program, and the inputs' program (NULL for None), both for the same bodies. */
static int hd_get_programs(PyObject *program, PyObject *inputs, hd_program **p, hd_program **in)
{
    *p = PyCapsule_GetPointer(program, PROGRAM);
    if (*p == NULL || (*p)->inverse_mass == NULL) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "program: a program with masses is needed");
        return -1;
    }
    *in = NULL;
    if (inputs != Py_None) {
        *in = PyCapsule_GetPointer(inputs, PROGRAM);
        if (*in == NULL)
            return -1;
        if ((*in)->bodies != (*p)->bodies) {
            PyErr_SetString(PyExc_ValueError, "inputs: a program for other bodies");
            return -1;
        }
    }
    return 0;
}

PyDoc_STRVAR(accelerations_doc,
"accelerations(program, inputs, oriented, q, v, out)\n\n"
"Write (ax, ay, alpha) per body into ``out`` from the state (q, v): each a C-contiguous\n"
"float64 array of 3 values per body.");

static PyObject *hd_py_accelerations(PyObject *self, PyObject *args)
{
    PyObject *program, *inputs, *qo, *vo, *outo;
    int oriented;
    hd_program *p, *in;
    if (!PyArg_ParseTuple(args, "OOpOOO:accelerations", &program, &inputs, &oriented, &qo,
                          &vo, &outo) ||
        hd_get_programs(program, inputs, &p, &in) < 0)
        return NULL;
    const Py_ssize_t n3 = 3 * p->bodies;
    Py_buffer qv, vv, ov;
    if (hd_get_buffer(qo, &qv, "q", 'd', n3, 0) < 0)
        return NULL;
    if (hd_get_buffer(vo, &vv, "v", 'd', n3, 0) < 0) {
        PyBuffer_Release(&qv);
        return NULL;
    }
    if (hd_get_buffer(outo, &ov, "out", 'd', n3, 1) < 0) {
        PyBuffer_Release(&qv);
        PyBuffer_Release(&vv);
        return NULL;
    }
    double *memory = malloc((size_t)(5 * p->bodies + 1) * sizeof(double));
    if (memory != NULL) {
        hd_scratch scratch = {memory, memory + p->bodies, memory + 2 * p->bodies};
        hd_accelerations(p, in, oriented, qv.buf, vv.buf, ov.buf, &scratch);
        free(memory);
    }
    PyBuffer_Release(&qv);
    PyBuffer_Release(&vv);
    PyBuffer_Release(&ov);
    if (memory == NULL)
        return PyErr_NoMemory();
    Py_RETURN_NONE;
}

/* The arguments of bound: the springs' program (or None), q, v,
 * the statics (masses, moments of inertia, floors), the unit of each body and the budget
 * (writable), checked against each other. */
typedef struct {
    hd_program *springs;
    Py_buffer views[5];  /* q, v, statics, unit, budget */
    long bodies, units;
} hd_bound_args;

static void hd_release_bound(hd_bound_args *a, int count)
{
    for (int k = 0; k < count; ++k)
        PyBuffer_Release(a->views + k);
}

static int hd_get_bound_args(hd_bound_args *a, PyObject *springs, PyObject *const objects[5])
{
    a->springs = NULL;
    if (springs != Py_None && (a->springs = PyCapsule_GetPointer(springs, PROGRAM)) == NULL)
        return -1;
    static const char *names[5] = {"q", "v", "statics", "unit", "budget"};
    int k = 0;
    for (; k < 5; ++k)
        if (hd_get_buffer(objects[k], a->views + k, names[k], k == 3 ? 'q' : 'd', -1, k == 4) < 0)
            break;
    if (k < 5) {
        hd_release_bound(a, k);
        return -1;
    }
    a->bodies = (long)(a->views[3].len / 8);
    a->units = (long)(a->views[4].len / 8 / HD_BUDGET_ROWS);
    const char *wrong = NULL;
    if (a->views[0].len != 24 * a->bodies || a->views[1].len != 24 * a->bodies)
        wrong = "q and v need 3 values per body";
    else if (a->views[2].len != 24 * a->bodies)
        wrong = "statics: 3 values per body are needed";
    else if (a->views[4].len != 8 * HD_BUDGET_ROWS * a->units)
        wrong = "budget: a whole number of columns of the budget's rows is needed";
    else if (a->springs != NULL && a->springs->bodies != a->bodies)
        wrong = "springs: a program for other bodies";
    const long *unit = a->views[3].buf;
    for (long b = 0; wrong == NULL && b < a->bodies; ++b)
        if (unit[b] < 0 || unit[b] >= a->units)
            wrong = "unit: a unit index is out of range";
    if (wrong != NULL) {
        PyErr_SetString(PyExc_ValueError, wrong);
        hd_release_bound(a, 5);
        return -1;
    }
    return 0;
}

/* Run the check (check != 0) or only the energies; -1 with an exception set. */
static int hd_run_bound(hd_bound_args *a, int check, double seconds, double growth, double *worst)
{
    double *memory = malloc((size_t)(2 * a->bodies + 1) * sizeof(double));
    if (memory == NULL) {
        hd_release_bound(a, 5);
        PyErr_NoMemory();
        return -1;
    }
    hd_scratch scratch = {memory, memory + a->bodies, NULL};
    const double *q = a->views[0].buf, *v = a->views[1].buf, *statics = a->views[2].buf;
    const long *unit = a->views[3].buf;
    double *budget = a->views[4].buf;
    if (check)
        *worst = hd_bound_check(a->springs, q, v, a->bodies, statics, unit, a->units, budget,
                                seconds, growth, &scratch);
    else
        hd_unit_energy(a->springs, q, v, a->bodies, statics, unit, a->units, budget, &scratch);
    free(memory);
    hd_release_bound(a, 5);
    return 0;
}

PyDoc_STRVAR(bound_doc,
"bound(springs, q, v, statics, unit, budget[, seconds, growth]) -> float or None\n\n"
"The energy bound (dynamics/divergence.py, with the same bits). Without ``seconds``: each unit's\n"
"energy of motion and springs at (q, v) into row ENERGY of ``budget`` and its excess over\n"
"the bodies' floors into row EXCESS (`_sums`). With them: one check (`_check_python`),\n"
"the budget advanced by ``seconds`` and the limits ``growth`` times its square; returns\n"
"the largest ratio of a unit's excess to its limit. ``springs``: a program of the\n"
"springs, or None; ``statics``: masses, moments of inertia and floors, one per body\n"
"each; ``unit``: int64, one per body; ``budget``: float64, writable, 8 rows of one value\n"
"per unit.");

static PyObject *hd_py_bound(PyObject *self, PyObject *args)
{
    PyObject *springs, *objects[5], *seconds = NULL;
    double growth = 0.0, worst = 0.0;
    hd_bound_args a;
    if (!PyArg_ParseTuple(args, "OOOOOO|Od:bound", &springs, objects, objects + 1,
                          objects + 2, objects + 3, objects + 4, &seconds, &growth))
        return NULL;
    const double interval = seconds == NULL ? 0.0 : PyFloat_AsDouble(seconds);
    if ((seconds != NULL && PyErr_Occurred()) || hd_get_bound_args(&a, springs, objects) < 0 ||
        hd_run_bound(&a, seconds != NULL, interval, growth, &worst) < 0)
        return NULL;
    if (seconds == NULL)
        Py_RETURN_NONE;
    return PyFloat_FromDouble(worst);
}

/* The writable buffers of a state (q, v) of `n3` values each, or -1 with an exception set
 * and neither held. */
static int hd_get_state(PyObject *q, PyObject *v, Py_ssize_t n3, Py_buffer *qv, Py_buffer *vv)
{
    if (hd_get_buffer(q, qv, "q", 'd', n3, 1) < 0)
        return -1;
    if (hd_get_buffer(v, vv, "v", 'd', n3, 1) < 0) {
        PyBuffer_Release(qv);
        return -1;
    }
    return 0;
}

/* A stepper capsule's contents: the kernel's stepper and the objects whose data it points
 * into, held for its lifetime. */
typedef struct {
    hd_stepper stepper;
    PyObject *program, *pair, *contacts;
} hd_stepper_capsule;

static void hd_stepper_destructor(PyObject *capsule)
{
    hd_stepper_capsule *c = PyCapsule_GetPointer(capsule, STEPPER);
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
    if (method == HD_EMBEDDED && (pair = PyCapsule_GetPointer(pair_object, PAIR)) == NULL)
        return NULL;
    if (contacts_object != Py_None) {
        if ((contacts = PyCapsule_GetPointer(contacts_object, CONTACTS)) == NULL)
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
    PyObject *capsule = PyCapsule_New(c, STEPPER, hd_stepper_destructor);
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
#define GIL_WORK 4096L

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
    hd_stepper_capsule *c = PyCapsule_GetPointer(args[0], STEPPER);
    if (c == NULL)
        return NULL;
    hd_stepper *s = &c->stepper;
    hd_program *in = NULL;
    if (args[1] != Py_None) {
        if ((in = PyCapsule_GetPointer(args[1], PROGRAM)) == NULL)
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
        if ((joints = PyCapsule_GetPointer(args[8], JOINTS)) == NULL)
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
    if (steps * s->program->bodies < GIL_WORK && s->contacts == NULL && joints == NULL) {
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
    hd_stepper_capsule *c = PyCapsule_GetPointer(capsule, STEPPER);
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


/* ------------------------------------------------------------------ the contact pass */

static void hd_contacts_destructor(PyObject *capsule)
{
    hd_contact_model *m = PyCapsule_GetPointer(capsule, CONTACTS);
    if (m != NULL)
        hd_coupled_free(m->coupled);
    hd_contact_free(m);
}

/* A copy of a buffer of `count` values (any count if < 0; `*got` the count read), or NULL
 * with an exception set. */
static void *hd_read_array(PyObject *object, const char *what, char format, Py_ssize_t count,
                           Py_ssize_t *got)
{
    Py_buffer view;
    if (hd_get_buffer(object, &view, what, format, count, 0) < 0)
        return NULL;
    void *copy = hd_copy_of(&view);
    if (got != NULL)
        *got = view.len / 8;
    PyBuffer_Release(&view);
    if (copy == NULL)
        PyErr_NoMemory();
    return copy;
}

/* Check the layout contact/compiled.py packed; -1 with an exception set if it is not one. */
static int hd_check_contacts(const hd_contact_model *m, const long *part_ints, Py_ssize_t reals,
                             long groups)
{
    Py_ssize_t used = 0;
    long last = -1;
    for (long p = 0; p < m->part_count; ++p) {
        const long body = part_ints[3 * p], kind = part_ints[3 * p + 1],
                   count = part_ints[3 * p + 2];
        if (body < last || body >= m->bodies || kind < HD_CIRCLE || kind > HD_OUTLINE ||
                (kind != HD_CIRCLE && count < 3)) {
            PyErr_SetString(PyExc_ValueError, "parts: not the layout of contact.h");
            return -1;
        }
        last = body;
        used += kind == HD_CIRCLE ? 3 : (kind == HD_POLYGON ? 4 : 2) * count;
    }
    if (used != reals) {
        PyErr_SetString(PyExc_ValueError, "part_reals: not the parts' values");
        return -1;
    }
    for (long w = 0; w < m->walls; ++w)
        if (m->wall_first[w] > m->wall_first[w + 1])
            goto bad;
    for (long k = 0; k < m->wall_first[m->walls]; ++k)
        if (m->wall_body[k] < 0 || m->wall_body[k] >= m->bodies)
            goto bad;
    for (long k = 0; k < m->colliding_count; ++k)
        if (m->colliding[k] < 0 || m->colliding[k] >= m->bodies)
            goto bad;
    for (long k = 0; k < m->apart_count; ++k) {
        const long *p = m->apart + 2 * k;
        if (p[0] < 0 || p[0] >= p[1] || p[1] >= m->bodies ||
                (k > 0 && (p[-2] > p[0] || (p[-2] == p[0] && p[-1] >= p[1]))))
            goto bad;
    }
    for (long b = 0; b < m->bodies; ++b)
        if (m->body_class[b] < -1 || m->body_class[b] >= m->class_count)
            goto bad;
    for (long k = 0; k < m->class_count * m->class_count; ++k)
        if (m->class_group[k] < -1 || m->class_group[k] >= groups)
            goto bad;
    return 0;
bad:
    PyErr_SetString(PyExc_ValueError, "walls, colliding, classes or apart: a body, class or "
                    "group out of range or apart not sorted");
    return -1;
}

/* The parts from the packed rows: `local` copied, `placed` allocated. */
static int hd_build_parts(hd_contact_model *m, const long *part_ints, const double *reals)
{
    m->parts = calloc((size_t)m->part_count + 1, sizeof(hd_part));
    m->part_first = calloc((size_t)m->bodies + 1, sizeof(long));
    if (m->parts == NULL || m->part_first == NULL)
        return -1;
    m->max_vertices = 1;
    for (long p = 0; p < m->part_count; ++p) {
        hd_part *part = m->parts + p;
        part->kind = (int)part_ints[3 * p + 1];
        part->count = part_ints[3 * p + 2];
        const size_t values = part->kind == HD_CIRCLE ? 3
                              : (size_t)((part->kind == HD_POLYGON ? 4 : 2) * part->count);
        part->local = malloc(values * sizeof(double));
        part->placed = malloc(values * sizeof(double));
        if (part->local == NULL || part->placed == NULL)
            return -1;
        memcpy(part->local, reals, values * sizeof(double));
        reals += values;
        if (part->count > m->max_vertices)
            m->max_vertices = part->count;
        m->part_first[part_ints[3 * p] + 1] += 1;
    }
    for (long b = 0; b < m->bodies; ++b)
        m->part_first[b + 1] += m->part_first[b];
    return 0;
}

PyDoc_STRVAR(contacts_doc,
"contacts(inverse_mass, inverse_inertia, reach, part_ints, part_reals, walls, wall_first,\n"
"         wall_body, colliding, classes, class_groups, materials, apart, threshold,\n"
"         thickness) -> Contacts\n\n"
"A scene's contact pass (contact.h): per body its inverse mass and inertia and reach;\n"
"per part (body, kind, vertex count) sorted by body, with its values in body axes; per\n"
"wall (nx, ny, offset, restitution, friction) and its bodies; the colliding bodies; per\n"
"body its class, per pair of classes their group, per group (restitution, friction), and\n"
"the pairs (i, j), sorted, that do not collide (contact/materials.py: PairMaterials).");

static PyObject *hd_py_contacts(PyObject *self, PyObject *args)
{
    PyObject *o[13];
    double threshold, thickness;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOOOdd:contacts", o, o + 1, o + 2, o + 3, o + 4,
                          o + 5, o + 6, o + 7, o + 8, o + 9, o + 10, o + 11, o + 12,
                          &threshold, &thickness))
        return NULL;
    hd_contact_model *m = calloc(1, sizeof(hd_contact_model));
    if (m == NULL)
        return PyErr_NoMemory();
    Py_ssize_t bodies, parts, reals, walls, wall_bodies, colliding, cells, materials, apart;
    long *part_ints = NULL;
    double *part_reals = NULL;
    m->threshold = threshold;
    m->thickness = thickness;
    if ((m->inverse_mass = hd_read_array(o[0], "inverse_mass", 'd', -1, &bodies)) == NULL ||
        (m->inverse_inertia = hd_read_array(o[1], "inverse_inertia", 'd', bodies, NULL)) == NULL ||
        (m->reach = hd_read_array(o[2], "reach", 'd', bodies, NULL)) == NULL ||
        (part_ints = hd_read_array(o[3], "part_ints", 'q', -1, &parts)) == NULL ||
        (part_reals = hd_read_array(o[4], "part_reals", 'd', -1, &reals)) == NULL ||
        (m->wall = hd_read_array(o[5], "walls", 'd', -1, &walls)) == NULL ||
        (m->wall_first = hd_read_array(o[6], "wall_first", 'q', walls / 5 + 1, NULL)) == NULL ||
        (m->wall_body = hd_read_array(o[7], "wall_body", 'q', -1, &wall_bodies)) == NULL ||
        (m->colliding = hd_read_array(o[8], "colliding", 'q', -1, &colliding)) == NULL ||
        (m->body_class = hd_read_array(o[9], "classes", 'q', bodies, NULL)) == NULL ||
        (m->class_group = hd_read_array(o[10], "class_groups", 'q', -1, &cells)) == NULL ||
        (m->material = hd_read_array(o[11], "materials", 'd', -1, &materials)) == NULL ||
        (m->apart = hd_read_array(o[12], "apart", 'q', -1, &apart)) == NULL)
        goto fail;
    m->bodies = (long)bodies;
    m->part_count = (long)(parts / 3);
    m->walls = (long)(walls / 5);
    m->colliding_count = (long)colliding;
    m->apart_count = (long)(apart / 2);
    while (m->class_count * m->class_count < cells)
        m->class_count += 1;
    if (parts % 3 || walls % 5 || apart % 2 || materials % 2 ||
            m->class_count * m->class_count != cells || m->wall_first[0] != 0 ||
            m->wall_first[m->walls] != wall_bodies) {
        PyErr_SetString(PyExc_ValueError, "contacts: arrays not of the layout of contact.h");
        goto fail;
    }
    if (hd_check_contacts(m, part_ints, reals, (long)(materials / 2)) < 0)
        goto fail;
    if (hd_build_parts(m, part_ints, part_reals) < 0 || hd_contact_prepare(m) < 0) {
        PyErr_NoMemory();
        goto fail;
    }
    free(part_ints);
    free(part_reals);
    PyObject *capsule = PyCapsule_New(m, CONTACTS, hd_contacts_destructor);
    if (capsule == NULL)
        hd_contact_free(m);
    return capsule;
fail:
    free(part_ints);
    free(part_reals);
    hd_contact_free(m);
    return NULL;
}

PyDoc_STRVAR(resolve_doc,
"resolve(contacts, q1, v1, q0, v0, h[, joints])\n\n"
"The contact pass after a step of ``h`` from (q0, v0) to (q1, v1): updates q1 and v1 in\n"
"place, sleeping bodies back at (q0, v0) (ContactPass.resolve); with the joint pass\n"
"``joints`` (not None), its last velocity rows solved with the contacts.");

static PyObject *hd_py_resolve(PyObject *self, PyObject *args)
{
    PyObject *capsule, *objects[4], *joints_object = Py_None;
    double h;
    if (!PyArg_ParseTuple(args, "OOOOOd|O:resolve", &capsule, objects, objects + 1, objects + 2,
                          objects + 3, &h, &joints_object))
        return NULL;
    hd_contact_model *m = PyCapsule_GetPointer(capsule, CONTACTS);
    if (m == NULL)
        return NULL;
    hd_joint_model *joints = NULL;
    if (joints_object != Py_None) {
        if ((joints = PyCapsule_GetPointer(joints_object, JOINTS)) == NULL)
            return NULL;
        for (long k = 0; k < joints->body_count; ++k)
            if (joints->bodies[k] >= m->bodies) {
                PyErr_SetString(PyExc_ValueError, "resolve: a joint pass for other bodies");
                return NULL;
            }
    }
    Py_buffer views[4];
    const char *names[4] = {"q1", "v1", "q0", "v0"};
    for (int k = 0; k < 4; ++k) {
        if (hd_get_buffer(objects[k], views + k, names[k], 'd', 3 * m->bodies, k < 2) < 0) {
            while (k-- > 0)
                PyBuffer_Release(views + k);
            return NULL;
        }
    }
    int status;
    Py_BEGIN_ALLOW_THREADS
    m->joints = joints;
    status = hd_resolve(m, views[0].buf, views[1].buf, views[2].buf, views[3].buf, h);
    m->joints = NULL;
    Py_END_ALLOW_THREADS
    for (int k = 0; k < 4; ++k)
        PyBuffer_Release(views + k);
    if (status < 0)
        return PyErr_NoMemory();
    Py_RETURN_NONE;
}

PyDoc_STRVAR(sleep_doc,
"sleep(contacts[, enabled, calm, rested, island]) -> (rested, island)\n\n"
"Sleeping of resting islands (ContactPass._doze): per body its rest time (s) and\n"
"sleeping island (-1: awake); with the arguments, first turn sleeping on or off and set\n"
"per body whether it may sleep (calm), its rest time and its island.");

static PyObject *hd_py_sleep(PyObject *self, PyObject *args)
{
    PyObject *capsule, *objects[3] = {NULL, NULL, NULL};
    int enabled = 0;
    if (!PyArg_ParseTuple(args, "O|iOOO:sleep", &capsule, &enabled, objects, objects + 1,
                          objects + 2))
        return NULL;
    hd_contact_model *m = PyCapsule_GetPointer(capsule, CONTACTS);
    if (m == NULL)
        return NULL;
    if (objects[0] != NULL) {
        if (objects[2] == NULL) {
            PyErr_SetString(PyExc_TypeError, "sleep: give enabled, calm, rested and island");
            return NULL;
        }
        Py_buffer views[3];
        const char *names[3] = {"calm", "rested", "island"};
        const char kinds[3] = {'q', 'd', 'q'};
        for (int k = 0; k < 3; ++k) {
            if (hd_get_buffer(objects[k], views + k, names[k], kinds[k], m->bodies, 0) < 0) {
                while (k-- > 0)
                    PyBuffer_Release(views + k);
                return NULL;
            }
        }
        const long long *calm = views[0].buf, *island = views[2].buf;
        const double *rested = views[1].buf;
        m->sleep = enabled != 0;
        for (long b = 0; b < m->bodies; ++b) {
            m->calm[b] = calm[b] != 0;
            m->rested[b] = rested[b];
            m->island[b] = (long)island[b];
        }
        for (int k = 0; k < 3; ++k)
            PyBuffer_Release(views + k);
    }
    PyObject *rested = PyList_New(m->bodies), *island = PyList_New(m->bodies);
    for (long b = 0; rested != NULL && island != NULL && b < m->bodies; ++b) {
        PyObject *t = PyFloat_FromDouble(m->rested[b]), *i = PyLong_FromLong(m->island[b]);
        if (t == NULL || i == NULL) {
            Py_XDECREF(t);
            Py_XDECREF(i);
            Py_CLEAR(rested);
            break;
        }
        PyList_SET_ITEM(rested, b, t);
        PyList_SET_ITEM(island, b, i);
    }
    if (rested == NULL || island == NULL) {
        Py_XDECREF(rested);
        Py_XDECREF(island);
        return NULL;
    }
    return Py_BuildValue("(NN)", rested, island);
}

PyDoc_STRVAR(warm_doc,
"warm(contacts[, impulses]) -> list\n\n"
"The impulses kept for warm starting, as (k0, k1, k2, k3, lx, ly, jn, jt) per contact,\n"
"those of one pair of parts (k0..k3) together and in the order the solver met them; with\n"
"``impulses``, replace them first.");

static PyObject *hd_py_warm(PyObject *self, PyObject *args)
{
    PyObject *capsule, *impulses = NULL;
    if (!PyArg_ParseTuple(args, "O|O:warm", &capsule, &impulses))
        return NULL;
    hd_contact_model *m = PyCapsule_GetPointer(capsule, CONTACTS);
    if (m == NULL)
        return NULL;
    if (impulses != NULL) {
        PyObject *items = PySequence_Fast(impulses, "impulses: a sequence of tuples");
        if (items == NULL)
            return NULL;
        const Py_ssize_t count = PySequence_Fast_GET_SIZE(items);
        hd_warm *warm = malloc(((size_t)count + 1) * sizeof(hd_warm));
        if (warm == NULL) {
            Py_DECREF(items);
            return PyErr_NoMemory();
        }
        for (Py_ssize_t i = 0; i < count; ++i) {
            hd_warm *w = warm + i;
            w->used = 0;
            if (!PyArg_ParseTuple(PySequence_Fast_GET_ITEM(items, i), "lllldddd", w->key,
                                  w->key + 1, w->key + 2, w->key + 3, &w->lx, &w->ly, &w->jn,
                                  &w->jt)) {
                free(warm);
                Py_DECREF(items);
                return NULL;
            }
        }
        Py_DECREF(items);
        free(m->warm);
        m->warm = warm;
        m->warm_count = m->warm_capacity = (long)count;
        hd_set_warm(m);
    }
    PyObject *list = PyList_New(m->warm_count);
    for (long i = 0; list != NULL && i < m->warm_count; ++i) {
        const hd_warm *w = m->warm + i;
        PyObject *item = Py_BuildValue("(lllldddd)", w->key[0], w->key[1], w->key[2],
                                       w->key[3], w->lx, w->ly, w->jn, w->jt);
        if (item == NULL)
            Py_CLEAR(list);
        else
            PyList_SET_ITEM(list, i, item);
    }
    return list;
}

/* ------------------------------------------------------------------ the joint pass */

static void hd_joints_destructor(PyObject *capsule)
{
    hd_joints_free(PyCapsule_GetPointer(capsule, JOINTS));
}

PyDoc_STRVAR(joints_doc,
"joints(bodies, inverse_mass, ints, reals, rows, pattern, rigid_pattern, turning,\n"
"       tolerance, max_turn) -> Joints\n\n"
"A scene's joint pass (joint.h): the model indices of the bodies it holds and their 1/m,\n"
"1/m, 1/I; per joint, in the order JointPass solves them, HD_JOINT_INTS ints and\n"
"HD_JOINT_REALS reals; ``rows``: the number of rows JointPass counts, which the kernel\n"
"checks against its own; the patterns of all rows and of the rigid rows (contact/sparse.py:\n"
"Pattern), each as (start, columns); the model indices of the bodies whose turning\n"
"JointPass.parts watches; the position stages' tolerance; the most an arm may turn in a\n"
"step (JointPass.max_turn).");

/* A contact/sparse.py Pattern from (start, columns); -1 with an exception set. */
static int hd_read_pattern(PyObject *pair, hd_pattern *p)
{
    PyObject *start_object, *columns_object;
    if (!PyArg_ParseTuple(pair, "OO:pattern", &start_object, &columns_object))
        return -1;
    Py_ssize_t count, length;
    long *start = hd_read_array(start_object, "start", 'q', -1, &length);
    long *columns = start == NULL ? NULL
                    : hd_read_array(columns_object, "columns", 'q', -1, &count);
    if (columns == NULL) {
        free(start);
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
        PyErr_SetString(PyExc_ValueError, "pattern: not a contact/sparse.py Pattern");
        return -1;
    }
    if (hd_pattern_init(p, rows, start, columns) < 0) {
        PyErr_NoMemory();
        return -1;
    }
    return 0;
}

static PyObject *hd_py_joints(PyObject *self, PyObject *args)
{
    PyObject *o[4], *patterns[2], *turning_object;
    long rows;
    double tolerance, max_turn;
    if (!PyArg_ParseTuple(args, "OOOOlOOOdd:joints", o, o + 1, o + 2, o + 3, &rows,
                          patterns, patterns + 1, &turning_object, &tolerance, &max_turn))
        return NULL;
    hd_joint_model *m = calloc(1, sizeof(hd_joint_model));
    if (m == NULL)
        return PyErr_NoMemory();
    Py_ssize_t bodies, ints_count, turning;
    long *ints = NULL;
    double *reals = NULL;
    if ((m->bodies = hd_read_array(o[0], "bodies", 'q', -1, &bodies)) == NULL ||
        (m->inverse_mass = hd_read_array(o[1], "inverse_mass", 'd', 3 * bodies, NULL)) == NULL ||
        (ints = hd_read_array(o[2], "ints", 'q', -1, &ints_count)) == NULL ||
        (reals = hd_read_array(o[3], "reals", 'd', ints_count / HD_JOINT_INTS * HD_JOINT_REALS,
                               NULL)) == NULL ||
        (m->turning = hd_read_array(turning_object, "turning", 'q', -1, &turning)) == NULL)
        goto fail;
    m->body_count = (long)bodies;
    m->turning_count = (long)turning;
    m->tolerance = tolerance, m->max_turn = max_turn;
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
    PyObject *capsule = PyCapsule_New(m, JOINTS, hd_joints_destructor);
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
    return HD_JOINT_STATE * m->joint_count + 2 * m->row_count + m->rigid_count + 2;
}

PyDoc_STRVAR(joint_state_doc,
"joint_state(joints, state, load)\n\n"
"Copy the joint pass's state (joint.h: HD_JOINT_STATE per joint, the warm-start impulses,\n"
"the Newton multipliers, the contact solve's extra impulses, 1.0 if the multipliers are\n"
"set, the last step's length) from ``state``\n"
"into the kernel (``load``) or from the kernel into ``state``.");

static PyObject *hd_py_joint_state(PyObject *self, PyObject *args)
{
    PyObject *capsule, *object;
    int load;
    if (!PyArg_ParseTuple(args, "OOp:joint_state", &capsule, &object, &load))
        return NULL;
    hd_joint_model *m = PyCapsule_GetPointer(capsule, JOINTS);
    Py_buffer view;
    if (m == NULL
        || hd_get_buffer(object, &view, "state", 'd', hd_joint_state_length(m), !load) < 0)
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
    } else {
        memcpy(s, m->warm, warm);
        memcpy(s + m->row_count, m->newton, newton);
        memcpy(s + m->row_count + m->rigid_count, m->extra, warm);
        s[flags] = m->newton_valid ? 1.0 : 0.0;
        s[flags + 1] = m->last_h;
    }
    PyBuffer_Release(&view);
    Py_RETURN_NONE;
}

PyDoc_STRVAR(joints_resolve_doc,
"joints_resolve(joints, bodies, q0, q1, v1, h)\n\n"
"The joint pass after a step of ``h`` from q0 to (q1, v1) of ``bodies`` bodies: updates\n"
"q1 and v1 in place (JointPass.resolve). Returns False, changing nothing, when the\n"
"positions have no solution near the step's end (JointsUnsolved), else True.");

static PyObject *hd_py_joints_resolve(PyObject *self, PyObject *args)
{
    PyObject *capsule, *objects[3];
    long bodies;
    double h;
    if (!PyArg_ParseTuple(args, "OlOOOd:joints_resolve", &capsule, &bodies, objects,
                          objects + 1, objects + 2, &h))
        return NULL;
    hd_joint_model *m = PyCapsule_GetPointer(capsule, JOINTS);
    if (m == NULL)
        return NULL;
    for (long k = 0; k < m->body_count; ++k)
        if (m->bodies[k] >= bodies) {
            PyErr_SetString(PyExc_ValueError, "joints_resolve: a joint's body out of range");
            return NULL;
        }
    Py_buffer views[3];
    const char *names[3] = {"q0", "q1", "v1"};
    for (int k = 0; k < 3; ++k) {
        if (hd_get_buffer(objects[k], views + k, names[k], 'd', 3 * bodies, k > 0) < 0) {
            while (k-- > 0)
                PyBuffer_Release(views + k);
            return NULL;
        }
    }
    int status;
    Py_BEGIN_ALLOW_THREADS
    status = hd_joints_resolve(m, views[0].buf, views[1].buf, views[2].buf, h);
    Py_END_ALLOW_THREADS
    for (int k = 0; k < 3; ++k)
        PyBuffer_Release(views + k);
    if (status == HD_JOINTS_OUT_OF_MEMORY)
        return PyErr_NoMemory();
    return PyBool_FromLong(status == HD_JOINTS_OK);
}

static PyMethodDef methods[] = {
    {"program", hd_py_program, METH_VARARGS, program_doc},
    {"pair", hd_py_pair, METH_VARARGS, pair_doc},
    {"accelerations", hd_py_accelerations, METH_VARARGS, accelerations_doc},
    {"stepper", hd_py_stepper, METH_VARARGS, stepper_doc},
    {"step", (PyCFunction)(void (*)(void))hd_py_step, METH_FASTCALL, step_doc},
    {"failed_state", hd_py_failed_state, METH_VARARGS, failed_state_doc},
    {"bound", hd_py_bound, METH_VARARGS, bound_doc},
    {"contacts", hd_py_contacts, METH_VARARGS, contacts_doc},
    {"resolve", hd_py_resolve, METH_VARARGS, resolve_doc},
    {"warm", hd_py_warm, METH_VARARGS, warm_doc},
    {"sleep", hd_py_sleep, METH_VARARGS, sleep_doc},
    {"joints", hd_py_joints, METH_VARARGS, joints_doc},
    {"joint_state", hd_py_joint_state, METH_VARARGS, joint_state_doc},
    {"joints_resolve", hd_py_joints_resolve, METH_VARARGS, joints_resolve_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernel",
    "The compiled kernel of hecker_dynamics (see hecker_dynamics.kernel).", -1, methods,
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
        {"MIN_ITERATIONS", HD_MIN_ITERATIONS}, {"WORK", HD_WORK},
        {"WIDE_UNITS", HD_WIDE_UNITS}, {"COLOURS", HD_COLOURS},
        {"POSITION_ITERATIONS", HD_POSITION_ITERATIONS}, {"MAX_CONTACT_SUBSTEPS", HD_MAX_SUBSTEPS},
        {"JOINTS_UNSOLVED", HD_UNSOLVED_JOINTS}, {"JOINT_NEWTON_ITERATIONS", HD_NEWTON_ITERATIONS},
        {"JOINT_MOST_SUBSTEPS", HD_MOST_SUBSTEPS},
        {"JOINT_DRIFT_ITERATIONS", HD_DRIFT_ITERATIONS},
        {"JOINT_MAX_ITERATIONS", HD_JOINT_MAX_ITERATIONS}, {"JOINT_INTS", HD_JOINT_INTS},
        {"JOINT_REALS", HD_JOINT_REALS}, {"JOINT_STATE", HD_JOINT_STATE},
        {"REVOLUTE", HD_REVOLUTE}, {"PRISMATIC", HD_PRISMATIC}, {"WELD", HD_WELD},
        {"ROD", HD_ROD}, {"ROPE", HD_ROPE}, {"GEAR", HD_GEAR},
    };
    PyObject *m = PyModule_Create(&module);
    if (m == NULL)
        return NULL;
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
        {"SLOP", HD_SLOP}, {"CORRECTION", HD_CORRECTION}, {"MAX_CORRECTION", HD_MAX_CORRECTION},
        {"JOINT_TOLERANCE", HD_JOINT_TOLERANCE}, {"JOINT_CONVERGED", HD_JOINT_CONVERGED},
        {"JOINT_ROUNDING", HD_JOINT_ROUNDING}, {"JOINT_MAX_TURN", HD_MAX_TURN},
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
