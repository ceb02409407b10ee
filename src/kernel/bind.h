/* What the binding files of hecker_dynamics._kernel share: the names of its capsules,
 * the buffer helpers, and each file's table of functions, which module.c registers.
 */
#ifndef HECKER_DYNAMICS_BIND_H
#define HECKER_DYNAMICS_BIND_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "kernel.h"

#define HD_PROGRAM_CAPSULE "hecker_dynamics._kernel.Program"
#define HD_PAIR_CAPSULE "hecker_dynamics._kernel.Pair"
#define HD_CONTACTS_CAPSULE "hecker_dynamics._kernel.Contacts"
#define HD_JOINTS_CAPSULE "hecker_dynamics._kernel.Joints"
#define HD_STEPPER_CAPSULE "hecker_dynamics._kernel.Stepper"
#define HD_LASER_CAPSULE "hecker_dynamics._kernel.Laser"

/* A C-contiguous buffer of `count` items of `format` ("d" or an 8-byte integer), or -1 with
 * an exception set. `count` < 0: any length, returned in view->len / itemsize. */
int hd_get_buffer(PyObject *object, Py_buffer *view, const char *what, char format,
                  Py_ssize_t count, int writable);

/* A copy of the buffer's bytes (malloc'd), or NULL out of memory. */
void *hd_copy_of(const Py_buffer *view);

/* The program, and the inputs' program (NULL for None), both for the same bodies. */
int hd_get_programs(PyObject *program, PyObject *inputs, hd_program **p, hd_program **in);

/* The writable buffers of a state (q, v) of `n3` values each, or -1 with an exception set
 * and neither held. */
int hd_get_state(PyObject *q, PyObject *v, Py_ssize_t n3, Py_buffer *qv, Py_buffer *vv);

/* A copy of a buffer of `count` values (any count if < 0; `*got` the count read), or NULL
 * with an exception set. */
void *hd_read_array(PyObject *object, const char *what, char format, Py_ssize_t count,
                    Py_ssize_t *got);

/* The arguments of a METH_FASTCALL | METH_KEYWORDS call of `function`, by name, without
 * the tuple and dict PyArg_ParseTupleAndKeywords needs (about 2 us a call with seven
 * keywords): `out[k]` the argument named `names[k]` (a NULL-terminated list), given by
 * position (the first `positional` at most) or by keyword, or NULL where left out. -1
 * with an exception set if one of the first `required` is missing, one is given twice, a
 * keyword is unknown or too many are given by position. */
int hd_arguments(const char *function, PyObject *const *args, Py_ssize_t nargs,
                 PyObject *kwnames, const char *const *names, int positional, int required,
                 PyObject **out);

/* hd_arguments for a call whose first argument is a capsule named `capsule` (a contact
 * pass, a joint pass, a stepper, a program): the pointer it holds, NULL with an exception
 * set. */
void *hd_capsule_arguments(const char *function, PyObject *const *args, Py_ssize_t nargs,
                           PyObject *kwnames, const char *const *names, int positional,
                           int required, const char *capsule, PyObject **out);

/* Each binding file's functions: bind_forces.c (dynamics/kernel.py's terms, pairs and
 * bound), bind_stepper.c (its whole steps), bind_contacts.c (contact/compiled.py),
 * bind_joints.c (contact/joints_kernel.py), bind_raycast.c (sensors/laser.py). */
extern PyMethodDef hd_bind_forces[], hd_bind_stepper[], hd_bind_contacts[], hd_bind_joints[],
    hd_bind_raycast[];

#endif
