/* hecker_dynamics._kernel: the Python binding of the compiled kernel.
 *
 * Arrays cross by the buffer protocol only (C-contiguous doubles and 64-bit integers), so
 * the module does not depend on numpy's C API or its version. hecker_dynamics/kernel.py
 * is the only caller; it packs the model's terms in the layout of kernel.h.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdlib.h>
#include <string.h>

#include "kernel.h"

static const char *PROGRAM = "hecker_dynamics._kernel.Program";
static const char *PAIR = "hecker_dynamics._kernel.Pair";

/* A C-contiguous buffer of `count` items of `format` ("d" or an 8-byte integer), or -1 with
 * an exception set. `count` < 0: any length, returned in view->len / itemsize. */
static int get_buffer(PyObject *object, Py_buffer *view, const char *what, char format,
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

static void free_program(Program *p)
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

static void program_destructor(PyObject *capsule)
{
    free_program(PyCapsule_GetPointer(capsule, PROGRAM));
}

static void *copy_of(const Py_buffer *view)
{
    void *copy = malloc(view->len > 0 ? (size_t)view->len : 1);
    if (copy != NULL && view->len > 0)
        memcpy(copy, view->buf, (size_t)view->len);
    return copy;
}

/* Check the body indices of a term: targets in [0, N), axes and point owners in [-1, N). */
static int check_bodies(const Term *t, long bodies)
{
    const int ni = hd_int_columns(t->kind);
    for (long e = 0; e < t->count; ++e) {
        const long *i = t->ints + ni * e;
        int ok = i[0] >= 0 && i[0] < bodies;
        if (t->kind == BODY_SPRING)
            ok = ok && i[1] >= 0 && i[1] < bodies;
        if (t->kind == WRENCH)
            ok = ok && i[1] >= -1 && i[1] < bodies && i[2] >= -1 && i[2] < bodies;
        if (!ok) {
            PyErr_Format(PyExc_ValueError, "term of kind %d, instance %ld: a body index is "
                         "out of range for %ld bodies", t->kind, e, bodies);
            return -1;
        }
    }
    return 0;
}

static int read_term(PyObject *item, Term *term, long bodies)
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
    if (get_buffer(ints, &iv, "term ints", 'q', -1, 0) < 0)
        return -1;
    term->count = (long)(iv.len / 8 / ni);
    if (iv.len != (Py_ssize_t)term->count * ni * 8 ||
        get_buffer(reals, &rv, "term reals", 'd', (Py_ssize_t)term->count * nr, 0) < 0) {
        if (!PyErr_Occurred())
            PyErr_Format(PyExc_ValueError, "term of kind %d: %zd ints is not a whole number "
                         "of rows of %d", term->kind, iv.len / 8, ni);
        PyBuffer_Release(&iv);
        return -1;
    }
    term->ints = copy_of(&iv);
    term->reals = copy_of(&rv);
    PyBuffer_Release(&iv);
    PyBuffer_Release(&rv);
    if (term->ints == NULL || term->reals == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    return check_bodies(term, bodies);
}

PyDoc_STRVAR(program_doc,
"program(bodies, inverse_mass, terms) -> capsule\n\n"
"Copy a model's force terms into a program: ``inverse_mass`` holds 1/m, 1/m, 1/I per body\n"
"(None for a program of inputs), ``terms`` is a sequence of (kind, ints, reals) with the\n"
"columns of kernel.h per instance, in the order they are summed.");

static PyObject *py_program(PyObject *self, PyObject *args)
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
    Program *p = calloc(1, sizeof(Program));
    Py_ssize_t count = PyTuple_GET_SIZE(sequence);
    if (p == NULL || (p->terms = calloc(count > 0 ? (size_t)count : 1, sizeof(Term))) == NULL) {
        free(p);
        Py_DECREF(sequence);
        return PyErr_NoMemory();
    }
    p->bodies = bodies;
    if (inverse_mass != Py_None) {
        Py_buffer view;
        if (get_buffer(inverse_mass, &view, "inverse_mass", 'd', 3 * bodies, 0) < 0)
            goto fail;
        p->inverse_mass = copy_of(&view);
        PyBuffer_Release(&view);
        if (p->inverse_mass == NULL) {
            PyErr_NoMemory();
            goto fail;
        }
    }
    for (Py_ssize_t t = 0; t < count; ++t) {
        p->term_count = (long)t + 1;  /* so that a failure frees what this term copied */
        if (read_term(PyTuple_GET_ITEM(sequence, t), p->terms + t, bodies) < 0)
            goto fail;
    }
    Py_DECREF(sequence);
    PyObject *capsule = PyCapsule_New(p, PROGRAM, program_destructor);
    if (capsule == NULL)
        free_program(p);
    return capsule;
fail:
    Py_DECREF(sequence);
    free_program(p);
    return NULL;
}

static void free_pair(Pair *pair)
{
    if (pair != NULL) {
        free(pair->a);
        free(pair->error);
        free(pair);
    }
}

static void pair_destructor(PyObject *capsule)
{
    free_pair(PyCapsule_GetPointer(capsule, PAIR));
}

PyDoc_STRVAR(pair_doc,
"pair(slopes, a, error, error_order) -> capsule\n\n"
"An embedded Runge-Kutta pair: ``a`` is slopes x (slopes - 1) coefficients (stages, then\n"
"the weights of the new state), ``error`` rows of ``slopes`` coefficients each.");

static PyObject *py_pair(PyObject *self, PyObject *args)
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
    if (get_buffer(a, &av, "a", 'd', slopes * (slopes - 1), 0) < 0)
        return NULL;
    if (get_buffer(error, &ev, "error", 'd', -1, 0) < 0) {
        PyBuffer_Release(&av);
        return NULL;
    }
    long rows = (long)(ev.len / 8 / slopes);
    Pair *pair = calloc(1, sizeof(Pair));
    if (rows < 1 || rows > 2 || ev.len != (Py_ssize_t)rows * slopes * 8) {
        PyErr_SetString(PyExc_ValueError, "error must hold 1 or 2 rows of `slopes` values");
    } else if (pair != NULL) {
        pair->slopes = slopes;
        pair->error_rows = rows;
        pair->error_order = error_order;
        pair->a = copy_of(&av);
        pair->error = copy_of(&ev);
        for (long r = 0; pair->error != NULL && r < rows; ++r)
            pair->needs_new_state |= pair->error[r * slopes + slopes - 1] != 0.0;
    }
    PyBuffer_Release(&av);
    PyBuffer_Release(&ev);
    if (PyErr_Occurred() || pair == NULL || pair->a == NULL || pair->error == NULL) {
        free_pair(pair);
        return PyErr_Occurred() ? NULL : PyErr_NoMemory();
    }
    PyObject *capsule = PyCapsule_New(pair, PAIR, pair_destructor);
    if (capsule == NULL)
        free_pair(pair);
    return capsule;
}

/* The program, and the inputs' program (NULL for None), both for the same bodies. */
static int get_programs(PyObject *program, PyObject *inputs, Program **p, Program **in)
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

static PyObject *py_accelerations(PyObject *self, PyObject *args)
{
    PyObject *program, *inputs, *qo, *vo, *outo;
    int oriented;
    Program *p, *in;
    if (!PyArg_ParseTuple(args, "OOpOOO:accelerations", &program, &inputs, &oriented, &qo,
                          &vo, &outo) ||
        get_programs(program, inputs, &p, &in) < 0)
        return NULL;
    const Py_ssize_t n3 = 3 * p->bodies;
    Py_buffer qv, vv, ov;
    if (get_buffer(qo, &qv, "q", 'd', n3, 0) < 0)
        return NULL;
    if (get_buffer(vo, &vv, "v", 'd', n3, 0) < 0) {
        PyBuffer_Release(&qv);
        return NULL;
    }
    if (get_buffer(outo, &ov, "out", 'd', n3, 1) < 0) {
        PyBuffer_Release(&qv);
        PyBuffer_Release(&vv);
        return NULL;
    }
    double *memory = malloc((size_t)(5 * p->bodies + 1) * sizeof(double));
    if (memory != NULL) {
        Scratch scratch = {memory, memory + p->bodies, memory + 2 * p->bodies};
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

PyDoc_STRVAR(advance_doc,
"advance(program, inputs, oriented, method, pair, tolerance, size, q, v, q_new, v_new, h,\n"
"        steps) -> (status, taken, evaluations, substeps, rejected, size)\n\n"
"Advance (q, v) in place by up to ``steps`` steps of ``h`` seconds with ``method``\n"
"(EXPLICIT_EULER, SEMI_IMPLICIT_EULER, VELOCITY_VERLET, RK4, or EMBEDDED: the ``pair`` at\n"
"``tolerance``, starting from sub-step ``size``), wrapping the angles after each step.\n"
"``status``: ADVANCED, NOT_FINITE (a new state was not finite; it is left in q_new,\n"
"v_new), SUBSTEP_UNDERFLOW or TOO_MANY_SUBSTEPS. The GIL is released meanwhile.");

static PyObject *py_advance(PyObject *self, PyObject *args)
{
    PyObject *program, *inputs, *pair_object, *qo, *vo, *qno, *vno;
    int oriented, method;
    double tolerance, size, h;
    long steps;
    Program *p, *in;
    Pair *pair = NULL;
    if (!PyArg_ParseTuple(args, "OOpiOddOOOOdl:advance", &program, &inputs, &oriented,
                          &method, &pair_object, &tolerance, &size, &qo, &vo, &qno, &vno, &h,
                          &steps) ||
        get_programs(program, inputs, &p, &in) < 0)
        return NULL;
    if (method < EXPLICIT_EULER || method > EMBEDDED) {
        PyErr_Format(PyExc_ValueError, "unknown method %d", method);
        return NULL;
    }
    if (method == EMBEDDED && (pair = PyCapsule_GetPointer(pair_object, PAIR)) == NULL)
        return NULL;
    const Py_ssize_t n3 = 3 * p->bodies;
    Py_buffer views[4];
    PyObject *objects[4] = {qo, vo, qno, vno};
    const char *names[4] = {"q", "v", "q_new", "v_new"};
    for (int k = 0; k < 4; ++k) {
        if (get_buffer(objects[k], views + k, names[k], 'd', n3, 1) < 0) {
            while (k-- > 0)
                PyBuffer_Release(views + k);
            return NULL;
        }
    }
    long taken = 0;
    Work work = {0, 0, 0};
    int status;
    Py_BEGIN_ALLOW_THREADS
    status = hd_advance(p, in, oriented, method, pair, tolerance, &size, views[0].buf,
                     views[1].buf, views[2].buf, views[3].buf, h, steps, &taken, &work);
    Py_END_ALLOW_THREADS
    for (int k = 0; k < 4; ++k)
        PyBuffer_Release(views + k);
    if (status == OUT_OF_MEMORY)
        return PyErr_NoMemory();
    return Py_BuildValue("illlld", status, taken, work.evaluations, work.substeps,
                         work.rejected, size);
}

static PyMethodDef methods[] = {
    {"program", py_program, METH_VARARGS, program_doc},
    {"pair", py_pair, METH_VARARGS, pair_doc},
    {"accelerations", py_accelerations, METH_VARARGS, accelerations_doc},
    {"advance", py_advance, METH_VARARGS, advance_doc},
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
        {"GRAVITY", GRAVITY}, {"ANCHOR_SPRING", ANCHOR_SPRING}, {"BODY_SPRING", BODY_SPRING},
        {"CENTER_DRAG", CENTER_DRAG}, {"POINT_DRAG", POINT_DRAG},
        {"ANGULAR_DAMPING", ANGULAR_DAMPING}, {"WRENCH", WRENCH},
        {"EXPLICIT_EULER", EXPLICIT_EULER}, {"SEMI_IMPLICIT_EULER", SEMI_IMPLICIT_EULER},
        {"VELOCITY_VERLET", VELOCITY_VERLET}, {"RK4", RK4}, {"EMBEDDED", EMBEDDED},
        {"ADVANCED", ADVANCED}, {"NOT_FINITE", NOT_FINITE},
        {"SUBSTEP_UNDERFLOW", SUBSTEP_UNDERFLOW}, {"TOO_MANY_SUBSTEPS", TOO_MANY_SUBSTEPS},
        {"MAX_SUBSTEPS", MAX_SUBSTEPS},
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
    return m;
}
