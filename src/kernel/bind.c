/* The helpers every binding file shares (bind.h): buffers checked and read, states and
 * programs taken from their objects.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdlib.h>
#include <string.h>

#include "bind.h"

/* A C-contiguous buffer of `count` items of `format` ("d" or an 8-byte integer), or -1 with
 * an exception set. `count` < 0: any length, returned in view->len / itemsize. */
int hd_get_buffer(PyObject *object, Py_buffer *view, const char *what, char format,
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

void *hd_copy_of(const Py_buffer *view)
{
    void *copy = malloc(view->len > 0 ? (size_t)view->len : 1);
    if (copy != NULL && view->len > 0)
        memcpy(copy, view->buf, (size_t)view->len);
    return copy;
}

/* The program, and the inputs' program (NULL for None), both for the same bodies. */
int hd_get_programs(PyObject *program, PyObject *inputs, hd_program **p, hd_program **in)
{
    *p = PyCapsule_GetPointer(program, HD_PROGRAM_CAPSULE);
    if (*p == NULL || (*p)->inverse_mass == NULL) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "program: a program with masses is needed");
        return -1;
    }
    *in = NULL;
    if (inputs != Py_None) {
        *in = PyCapsule_GetPointer(inputs, HD_PROGRAM_CAPSULE);
        if (*in == NULL)
            return -1;
        if ((*in)->bodies != (*p)->bodies) {
            PyErr_SetString(PyExc_ValueError, "inputs: a program for other bodies");
            return -1;
        }
    }
    return 0;
}

/* The writable buffers of a state (q, v) of `n3` values each, or -1 with an exception set
 * and neither held. */
int hd_get_state(PyObject *q, PyObject *v, Py_ssize_t n3, Py_buffer *qv, Py_buffer *vv)
{
    if (hd_get_buffer(q, qv, "q", 'd', n3, 1) < 0)
        return -1;
    if (hd_get_buffer(v, vv, "v", 'd', n3, 1) < 0) {
        PyBuffer_Release(qv);
        return -1;
    }
    return 0;
}

/* A copy of a buffer of `count` values (any count if < 0; `*got` the count read), or NULL
 * with an exception set. */
void *hd_read_array(PyObject *object, const char *what, char format, Py_ssize_t count,
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

int hd_arguments(const char *function, PyObject *const *args, Py_ssize_t nargs,
                 PyObject *kwnames, const char *const *names, int positional, int required,
                 PyObject **out)
{
    int count = 0;
    while (names[count] != NULL)
        out[count++] = NULL;
    if (nargs > positional) {
        PyErr_Format(PyExc_TypeError, "%s() takes at most %d positional arguments (%zd given)",
                     function, positional, nargs);
        return -1;
    }
    for (Py_ssize_t k = 0; k < nargs; ++k)
        out[k] = args[k];
    const Py_ssize_t keywords = kwnames == NULL ? 0 : PyTuple_GET_SIZE(kwnames);
    for (Py_ssize_t i = 0; i < keywords; ++i) {
        PyObject *key = PyTuple_GET_ITEM(kwnames, i);
        /* Keywords mostly come in the order of the names: try the next one first. */
        int k = (int)(nargs + i) < count ? (int)(nargs + i) : 0, tried = 0;
        while (tried < count && PyUnicode_CompareWithASCIIString(key, names[k]) != 0) {
            k = (k + 1) % count;
            ++tried;
        }
        if (tried == count) {
            PyErr_Format(PyExc_TypeError, "%s() got an unexpected keyword argument '%U'",
                         function, key);
            return -1;
        }
        if (out[k] != NULL) {
            PyErr_Format(PyExc_TypeError, "%s() got multiple values for argument '%s'",
                         function, names[k]);
            return -1;
        }
        out[k] = args[nargs + i];
    }
    for (int k = 0; k < required; ++k)
        if (out[k] == NULL) {
            PyErr_Format(PyExc_TypeError, "%s() missing required argument '%s'", function,
                         names[k]);
            return -1;
        }
    return 0;
}

void *hd_capsule_arguments(const char *function, PyObject *const *args, Py_ssize_t nargs,
                           PyObject *kwnames, const char *const *names, int positional,
                           int required, const char *capsule, PyObject **out)
{
    if (hd_arguments(function, args, nargs, kwnames, names, positional, required, out) < 0)
        return NULL;
    return PyCapsule_GetPointer(out[0], capsule);
}
