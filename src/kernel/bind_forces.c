/* The binding of the force terms (kernel.h, forces.c) and the energy bound (bound.c) for
 * hecker_dynamics/dynamics/kernel.py: program, pair, accelerations, bound and
 * wrench_values (the inputs' new values in place), each taking keyword arguments.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdlib.h>
#include <string.h>

#include "bind.h"
#include "kernel.h"

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
    hd_free_program(PyCapsule_GetPointer(capsule, HD_PROGRAM_CAPSULE));
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
"Copy a model's force terms into a program of ``bodies`` bodies: ``inverse_mass`` holds\n"
"1/m (1/kg), 1/m, 1/I (1/(kg m^2)) per body, C-contiguous float64 (None for a program of\n"
"inputs), ``terms`` is a sequence of (kind, ints, reals), kind a term's code (GRAVITY ...),\n"
"ints int64 and reals float64 rows with the columns of kernel.h per instance, in the order\n"
"they are summed.");

static PyObject *hd_py_program(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"bodies", "inverse_mass", "terms", NULL};
    long bodies;
    PyObject *inverse_mass, *terms;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "lOO:program", names, &bodies,
                                     &inverse_mass, &terms))
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
    PyObject *capsule = PyCapsule_New(p, HD_PROGRAM_CAPSULE, hd_program_destructor);
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
    hd_free_pair(PyCapsule_GetPointer(capsule, HD_PAIR_CAPSULE));
}

PyDoc_STRVAR(pair_doc,
"pair(slopes, a, error, error_order) -> capsule\n\n"
"An embedded Runge-Kutta pair of ``slopes`` slopes (2 to 64): ``a`` is slopes x (slopes -\n"
"1) coefficients, C-contiguous float64 (stages, then the weights of the new state),\n"
"``error`` 1 or 2 rows of ``slopes`` coefficients each, ``error_order`` the order of the\n"
"error estimate (int).");

static PyObject *hd_py_pair(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"slopes", "a", "error", "error_order", NULL};
    long slopes;
    int error_order;
    PyObject *a, *error;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "lOOi:pair", names, &slopes, &a, &error,
                                     &error_order))
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
    PyObject *capsule = PyCapsule_New(pair, HD_PAIR_CAPSULE, hd_pair_destructor);
    if (capsule == NULL)
        hd_free_pair(pair);
    return capsule;
}

PyDoc_STRVAR(accelerations_doc,
"accelerations(program, inputs, oriented, q, v, out)\n\n"
"Write (ax, ay, alpha) (m/s^2, rad/s^2) per body into ``out`` from the state (q, v),\n"
"(x, y, angle) and (vx, vy, omega) of each CM: each a C-contiguous float64 array of 3\n"
"values per body; the forces of ``program`` (program()) and of the inputs' program\n"
"``inputs`` (None: none); ``oriented``: some active force needs the angles.");

static PyObject *hd_py_accelerations(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                                     PyObject *kwnames)
{
    static const char *const names[] = {"program", "inputs", "oriented", "q", "v", "out",
                                        NULL};
    PyObject *given[6];
    hd_program *p, *in;
    if (hd_arguments("accelerations", args, nargs, kwnames, names, 6, 6, given) < 0 ||
        hd_get_programs(given[0], given[1], &p, &in) < 0)
        return NULL;
    PyObject *qo = given[3], *vo = given[4], *outo = given[5];
    const int oriented = PyObject_IsTrue(given[2]);
    if (oriented < 0)
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

PyDoc_STRVAR(wrench_values_doc,
"wrench_values(program, values)\n\n"
"Give the wrenches of the inputs' ``program`` (program() of one WRENCH term, no masses)\n"
"new values in place, where they act as before: ``values`` is a list of floats, the force\n"
"(fx, fy, N) and torque (N m) of each row in turn, 3 per row. The program is left as it was\n"
"if a value is refused.");

static PyObject *hd_py_wrench_values(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                                     PyObject *kwnames)
{
    static const char *const names[] = {"program", "values", NULL};
    PyObject *given[2];
    hd_program *p = hd_capsule_arguments("wrench_values", args, nargs, kwnames, names, 2, 2,
                                         HD_PROGRAM_CAPSULE, given);
    if (p == NULL)
        return NULL;
    if (p->term_count != 1 || p->terms[0].kind != HD_WRENCH) {
        PyErr_SetString(PyExc_ValueError, "program: a program of one wrench term is needed");
        return NULL;
    }
    hd_term *term = p->terms;
    if (!PyList_Check(given[1]) || PyList_GET_SIZE(given[1]) != 3 * term->count) {
        PyErr_Format(PyExc_ValueError, "values: a list of %ld floats is needed",
                     3 * term->count);
        return NULL;
    }
    double *values = malloc((size_t)(3 * term->count + 1) * sizeof(double));
    if (values == NULL)
        return PyErr_NoMemory();
    for (long k = 0; k < 3 * term->count; ++k) {
        values[k] = PyFloat_AsDouble(PyList_GET_ITEM(given[1], k));
        if (values[k] == -1.0 && PyErr_Occurred()) {
            free(values);
            return NULL;
        }
    }
    for (long e = 0; e < term->count; ++e)  /* reals: fx, fy, torque, px, py (kernel.h) */
        memcpy(term->reals + 5 * e, values + 3 * e, 3 * sizeof(double));
    free(values);
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
    if (springs != Py_None
        && (a->springs = PyCapsule_GetPointer(springs, HD_PROGRAM_CAPSULE)) == NULL)
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
"bound(springs, q, v, statics, unit, budget, seconds=None, growth=0.0) -> float or None\n\n"
"The energy bound (dynamics/divergence.py, with the same bits). Without ``seconds``: each unit's\n"
"energy of motion and springs at (q, v) into row ENERGY of ``budget`` and its excess over\n"
"the bodies' floors into row EXCESS (`_sums`). With them: one check (`_check_python`),\n"
"the budget advanced by ``seconds`` and the limits ``growth`` times its square; returns\n"
"the largest ratio of a unit's excess to its limit. ``springs``: a program of the\n"
"springs, or None; ``statics``: masses, moments of inertia and floors, one per body\n"
"each (float64; kg, kg m^2, J); ``unit``: int64, one per body; ``budget``: float64,\n"
"writable, HD_BUDGET_ROWS rows (kernel.h) of one value per unit; (q, v): (x, y, angle)\n"
"and (vx, vy, omega) of each CM, C-contiguous float64; ``seconds`` (s).");

static PyObject *hd_py_bound(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                             PyObject *kwnames)
{
    static const char *const names[] = {"springs", "q", "v", "statics", "unit", "budget",
                                        "seconds", "growth", NULL};
    PyObject *given[8];
    if (hd_arguments("bound", args, nargs, kwnames, names, 8, 6, given) < 0)
        return NULL;
    PyObject *springs = given[0], *const *objects = given + 1;
    PyObject *seconds = given[6] != Py_None ? given[6] : NULL;
    double growth = 0.0, worst = 0.0;
    if (given[7] != NULL && (growth = PyFloat_AsDouble(given[7])) == -1.0 && PyErr_Occurred())
        return NULL;
    hd_bound_args a;
    const double interval = seconds == NULL ? 0.0 : PyFloat_AsDouble(seconds);
    if ((seconds != NULL && PyErr_Occurred()) || hd_get_bound_args(&a, springs, objects) < 0 ||
        hd_run_bound(&a, seconds != NULL, interval, growth, &worst) < 0)
        return NULL;
    if (seconds == NULL)
        Py_RETURN_NONE;
    return PyFloat_FromDouble(worst);
}

PyMethodDef hd_bind_forces[] = {
    {"program", (PyCFunction)(void (*)(void))hd_py_program, METH_VARARGS | METH_KEYWORDS,
     program_doc},
    {"pair", (PyCFunction)(void (*)(void))hd_py_pair, METH_VARARGS | METH_KEYWORDS, pair_doc},
    {"accelerations", (PyCFunction)(void (*)(void))hd_py_accelerations,
     METH_FASTCALL | METH_KEYWORDS, accelerations_doc},
    {"bound", (PyCFunction)(void (*)(void))hd_py_bound, METH_FASTCALL | METH_KEYWORDS,
     bound_doc},
    {"wrench_values", (PyCFunction)(void (*)(void))hd_py_wrench_values,
     METH_FASTCALL | METH_KEYWORDS, wrench_values_doc},
    {NULL, NULL, 0, NULL},
};
