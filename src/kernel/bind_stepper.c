/* The binding of whole steps (steppers.c) for hecker_dynamics/dynamics/kernel.py:
 * stepper (with what run's calls share), step, run (steps with the energy bound's checks
 * at the publish instants), failed_state, keep_starts and step_start, each taking keyword
 * arguments.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdlib.h>
#include <string.h>

#include "bind.h"
#include "contact.h"
#include "drive.h"
#include "joint.h"
#include "kernel.h"

/* What run needs that stays the same from call to call, given when its stepper is built:
 * the step `h` (s), the steps `per` from one publish instant to the next and their
 * `period_seconds`, and the energy bound's data (dynamics/divergence.py): the springs'
 * program (NULL: none), the statics (masses, moments of inertia, floors), the unit of each
 * body, the budget (writable; its `units` columns) and the `growth` of its limits.
 * `per` 0: the stepper takes no runs. */
typedef struct {
    double h, period_seconds, growth;
    long per, units;
    hd_program *springs;
    Py_buffer statics, unit, budget;
} hd_run_bound;

/* Release the buffers of a run's data that has them (per > 0). */
static void hd_release_run_bound(hd_run_bound *b)
{
    if (b->per < 1)
        return;
    PyBuffer_Release(&b->statics);
    PyBuffer_Release(&b->unit);
    PyBuffer_Release(&b->budget);
    b->per = 0;
}

/* A stepper capsule's contents: the kernel's stepper, run's data, and the objects whose
 * data they point into, held for its lifetime. */
typedef struct {
    hd_stepper stepper;
    hd_run_bound run;
    PyObject *program, *pair, *contacts, *springs;
} hd_stepper_capsule;

static void hd_stepper_destructor(PyObject *capsule)
{
    hd_stepper_capsule *c = PyCapsule_GetPointer(capsule, HD_STEPPER_CAPSULE);
    if (c == NULL)
        return;
    hd_stepper_free(&c->stepper);
    hd_release_run_bound(&c->run);
    Py_XDECREF(c->program);
    Py_XDECREF(c->pair);
    Py_XDECREF(c->contacts);
    Py_XDECREF(c->springs);
    free(c);
}

/* Read run's data into `b` for `bodies` bodies: the energy bound's `objects` (springs,
 * statics, unit, budget), whose buffers it then holds, unless the budget is None (no runs;
 * `b->per` 0); -1 with an exception set and nothing held. */
static int hd_get_run_bound(hd_run_bound *b, long bodies, PyObject *const objects[4])
{
    const long per = b->per;
    b->per = 0;
    if (objects[3] == Py_None)
        return 0;
    if (per < 1 || !(b->h > 0.0)) {
        PyErr_SetString(PyExc_ValueError, "stepper: runs need a step h > 0 and per >= 1");
        return -1;
    }
    b->springs = NULL;
    if (objects[0] != Py_None
        && (b->springs = PyCapsule_GetPointer(objects[0], HD_PROGRAM_CAPSULE)) == NULL)
        return -1;
    if (b->springs != NULL && b->springs->bodies != bodies) {
        PyErr_SetString(PyExc_ValueError, "springs: a program for other bodies");
        return -1;
    }
    if (hd_get_buffer(objects[1], &b->statics, "statics", 'd', 3 * bodies, 0) < 0)
        return -1;
    if (hd_get_buffer(objects[2], &b->unit, "unit", 'q', bodies, 0) < 0) {
        PyBuffer_Release(&b->statics);
        return -1;
    }
    if (hd_get_buffer(objects[3], &b->budget, "budget", 'd', -1, 1) < 0) {
        PyBuffer_Release(&b->statics);
        PyBuffer_Release(&b->unit);
        return -1;
    }
    b->per = per;
    b->units = (long)(b->budget.len / 8 / HD_BUDGET_ROWS);
    const char *wrong = b->budget.len != 8 * HD_BUDGET_ROWS * b->units
                        ? "budget: a whole number of columns of the budget's rows is needed" : NULL;
    const long *unit = b->unit.buf;
    for (long k = 0; wrong == NULL && k < bodies; ++k)
        if (unit[k] < 0 || unit[k] >= b->units)
            wrong = "unit: a unit index is out of range";
    if (wrong != NULL) {
        PyErr_SetString(PyExc_ValueError, wrong);
        hd_release_run_bound(b);
        return -1;
    }
    return 0;
}

PyDoc_STRVAR(stepper_doc,
"stepper(program, method, pair, tolerance, contacts, *, h=0.0, per=0, period_seconds=0.0,\n"
"        springs=None, statics=None, unit=None, budget=None, growth=0.0) -> Stepper\n\n"
"Whole steps of ``method`` (int: EXPLICIT_EULER, SEMI_IMPLICIT_EULER, VELOCITY_VERLET, RK4,\n"
"or EMBEDDED with the Pair ``pair`` (pair(), else None) and the sub-steps' relative\n"
"``tolerance``) on the forces' ``program`` (program()), with the contact pass ``contacts``\n"
"(contacts(), None: none) after each step, and the memory they need, for ``step``; and for\n"
"``run``, what its calls share (budget None: no runs): the step ``h`` (s), the steps\n"
"``per`` (int) from one publish instant to the next and their ``period_seconds`` (s), and\n"
"the energy bound's data (``bound``'s), held for the stepper's lifetime: the springs'\n"
"program ``springs`` (None: none), ``statics`` (float64, 3 per body), ``unit`` (int64,\n"
"each body's unit), ``budget`` (float64, HD_BUDGET_ROWS rows (kernel.h) of a column per\n"
"unit, written by each run) and the limits' ``growth``.");

static PyObject *hd_py_stepper(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"program", "method", "pair", "tolerance", "contacts", "h", "per",
                            "period_seconds", "springs", "statics", "unit", "budget",
                            "growth", NULL};
    PyObject *program, *pair_object, *contacts_object;
    PyObject *bound[4] = {Py_None, Py_None, Py_None, Py_None};
    int method;
    double tolerance;
    hd_run_bound run = {0.0, 0.0, 0.0, 0, 0, NULL};
    hd_program *p, *unused;
    hd_pair *pair = NULL;
    hd_contact_model *contacts = NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OiOdO|$dldOOOOd:stepper", names,
                                     &program, &method, &pair_object, &tolerance,
                                     &contacts_object, &run.h, &run.per, &run.period_seconds,
                                     &bound[0], &bound[1], &bound[2], &bound[3], &run.growth) ||
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
    if (hd_get_run_bound(&run, p->bodies, bound) < 0)
        return NULL;
    hd_stepper_capsule *c = calloc(1, sizeof(hd_stepper_capsule));
    if (c == NULL) {
        hd_release_run_bound(&run);
        return PyErr_NoMemory();
    }
    if (hd_stepper_init(&c->stepper, p, method, pair, tolerance, contacts) != HD_ADVANCED) {
        hd_release_run_bound(&run);
        free(c);
        return PyErr_NoMemory();
    }
    c->run = run;
    PyObject *capsule = PyCapsule_New(c, HD_STEPPER_CAPSULE, hd_stepper_destructor);
    if (capsule == NULL) {
        hd_stepper_free(&c->stepper);
        hd_release_run_bound(&c->run);
        free(c);
        return NULL;
    }
    c->program = Py_NewRef(program);
    c->pair = Py_NewRef(pair_object);
    c->contacts = Py_NewRef(contacts_object);
    c->springs = Py_NewRef(bound[0]);
    return capsule;
}

/* Body-steps of work below which a call keeps the GIL: releasing and taking it back costs
 * more than such a call's steps. */
#define HD_GIL_WORK 4096L

PyDoc_STRVAR(step_doc,
"step(stepper, inputs, oriented, q, v, h, steps, size, joints)\n"
"    -> (status, taken, evaluations, substeps, rejected, size)\n\n"
"Advance (q, v), (x, y, angle) and (vx, vy, omega) of each CM, C-contiguous float64 of 3\n"
"values per body, in place by up to ``steps`` (int) steps of ``h`` (s) with the Stepper\n"
"``stepper``'s method and passes, the inputs' program ``inputs`` (program(), None: none)\n"
"added to its forces (an embedded pair starting from sub-step ``size`` (s)), wrapping the\n"
"angles after each step. ``oriented``: some active force needs the angles; ``joints``\n"
"(joints(), None: none): the joint pass before the contacts. ``status``: ADVANCED,\n"
"NOT_FINITE (a new state was not finite; ``failed_state`` gives it), SUBSTEP_UNDERFLOW,\n"
"TOO_MANY_SUBSTEPS or JOINTS_UNSOLVED. The GIL is released meanwhile, unless the call is\n"
"short.");

/* The arguments of a fast call of step or run (`function`), the `count` of `names` read
 * into `given` by hd_arguments, by position or keyword (the first `required` of them
 * needed, the others NULL where left out), and the first three, (stepper, inputs,
 * oriented), read: the stepper's capsule, the inputs' program (NULL for None) and
 * `oriented`; NULL with an exception set. */
static hd_stepper_capsule *hd_get_stepping(const char *function, PyObject *const *args,
                                           Py_ssize_t nargs, PyObject *kwnames,
                                           const char *const *names, int count, int required,
                                           PyObject **given, hd_program **in, int *oriented)
{
    hd_stepper_capsule *c = hd_capsule_arguments(function, args, nargs, kwnames, names, count,
                                                 required, HD_STEPPER_CAPSULE, given);
    if (c == NULL)
        return NULL;
    *in = NULL;
    if (given[1] != Py_None) {
        if ((*in = PyCapsule_GetPointer(given[1], HD_PROGRAM_CAPSULE)) == NULL)
            return NULL;
        if ((*in)->bodies != c->stepper.program->bodies) {
            PyErr_SetString(PyExc_ValueError, "inputs: a program for other bodies");
            return NULL;
        }
    }
    *oriented = PyObject_IsTrue(given[2]);
    return *oriented < 0 ? NULL : c;
}

static PyObject *hd_py_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                            PyObject *kwnames)
{
    static const char *const names[] = {"stepper", "inputs", "oriented", "q", "v", "h",
                                        "steps", "size", "joints", NULL};
    PyObject *given[9];
    hd_program *in;
    int oriented;
    hd_stepper_capsule *c = hd_get_stepping("step", args, nargs, kwnames, names, 9, 9, given, &in,
                                            &oriented);
    if (c == NULL)
        return NULL;
    hd_stepper *s = &c->stepper;
    const double h = PyFloat_AsDouble(given[5]);
    const long steps = PyLong_AsLong(given[6]);
    double size = PyFloat_AsDouble(given[7]);
    if (PyErr_Occurred())
        return NULL;
    hd_joint_model *joints = NULL;
    if (given[8] != Py_None) {
        if ((joints = PyCapsule_GetPointer(given[8], HD_JOINTS_CAPSULE)) == NULL)
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
    if (hd_get_state(given[3], given[4], 3 * s->program->bodies, &qv, &vv) < 0)
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

/* The steps of run: the segments from the start to the first publish instant (`first` steps)
 * and from each instant to the next (b->per), `steps` in all; segment k steps in slot k of
 * (qs, vs), from a copy of the slot before (of (q0, v0) for the first). After each segment
 * that ends on an instant, the energy bound's check over `first_seconds` (the first) or
 * b->period_seconds; a check over 1 ends the run. */
static int hd_run_segments(hd_stepper *s, const hd_run_bound *b, hd_program *in,
                           hd_drives *drives, int oriented, double *size, const double *q0,
                           const double *v0, double *qs, double *vs, long first, long steps,
                           double first_seconds, double *scratch_memory, long *taken,
                           hd_work *work, long *checked, double *worst)
{
    const long n = s->program->bodies, n3 = 3 * n, per = b->per;
    const size_t bytes = (size_t)n3 * sizeof(double);
    hd_scratch scratch = {scratch_memory, scratch_memory + n, NULL};
    const double *from_q = q0, *from_v = v0;
    long done = 0, end = first < steps ? first : steps;
    *taken = 0;
    *checked = 0;
    *worst = 0.0;
    for (long k = 0; done < steps; ++k) {
        double *q = qs + k * n3, *v = vs + k * n3;
        memcpy(q, from_q, bytes);
        memcpy(v, from_v, bytes);
        /* The drives' instants inside the run, each after the check of its publish
         * instant; one the drives leave to Python ends the run there. */
        if (drives != NULL && done > 0 && hd_drives_next(drives) == done) {
            const int arrived = hd_drives_arrive(drives, done, q, v, in, b->budget.buf,
                                                 b->units);
            if (arrived < 1)
                return arrived < 0 ? HD_OUT_OF_MEMORY : HD_ADVANCED;
        }
        while (done < end) {
            const long next = drives == NULL ? end : hd_drives_next(drives);
            const long stop = next > done && next < end ? next : end;
            long segment = 0;
            const int status = hd_stepper_advance(s, in, oriented, NULL, size, q, v, b->h,
                                                  stop - done, &segment, work);
            *taken += segment;
            if (status != HD_ADVANCED)
                return status;
            done = stop;
            if (done < end) {
                const int arrived = hd_drives_arrive(drives, done, q, v, in, b->budget.buf,
                                                     b->units);
                if (arrived < 1)
                    return arrived < 0 ? HD_OUT_OF_MEMORY : HD_ADVANCED;
            }
        }
        if (done == first + k * per) {  /* a publish instant */
            const double ratio = hd_bound_check(
                b->springs, q, v, n, b->statics.buf, b->unit.buf, b->units, b->budget.buf,
                k == 0 ? first_seconds : b->period_seconds, b->growth, &scratch);
            *checked += 1;
            if (ratio > *worst)
                *worst = ratio;
            if (!(ratio <= 1.0))
                return HD_ADVANCED;
            /* the rates of work of the inputs now */
            if (drives != NULL && hd_drives_refresh(drives, in, b->budget.buf, b->units) < 0)
                return HD_OUT_OF_MEMORY;
        }
        end = done + per < steps ? done + per : steps;
        from_q = q;
        from_v = v;
    }
    return HD_ADVANCED;
}

/* |(x, y)| by the Python callable `context` (math.hypot), with the GIL taken for it. */
static double hd_call_hypot(void *context, double x, double y, int *failed)
{
    const PyGILState_STATE gil = PyGILState_Ensure();
    double length = NAN;
    PyObject *values[2] = {PyFloat_FromDouble(x), PyFloat_FromDouble(y)};
    if (values[0] != NULL && values[1] != NULL) {
        PyObject *result = PyObject_Vectorcall((PyObject *)context, values, 2, NULL);
        if (result != NULL) {
            length = PyFloat_AsDouble(result);
            Py_DECREF(result);
        }
    }
    Py_XDECREF(values[0]);
    Py_XDECREF(values[1]);
    if (PyErr_Occurred()) {  /* out of memory: the instant is left to Python */
        PyErr_Clear();
        *failed = 1;
    }
    PyGILState_Release(gil);
    return length;
}

/* The drives' buffers a run holds while it takes them. */
typedef struct {
    Py_buffer views[5];
    int held;
} hd_drive_views;

static void hd_release_drives(hd_drive_views *views)
{
    for (int k = 0; k < views->held; ++k)
        PyBuffer_Release(&views->views[k]);
    views->held = 0;
}

/* Read run's `drives` (a tuple: ints, reals, row_unit, row_rates, steady, start_ns, step_ns,
 * hypot) into `d` for the inputs' program `in`, the energy bound's `units` and `bodies`
 * bodies, holding its buffers in `views`; -1 with an exception set. */
static int hd_get_drives(PyObject *object, const hd_program *in, long units, long bodies,
                         double h, hd_drives *d, hd_drive_views *views)
{
    if (!PyTuple_Check(object) || PyTuple_GET_SIZE(object) != 8) {
        PyErr_SetString(PyExc_TypeError, "drives: a tuple of 8 items is needed");
        return -1;
    }
    if (in == NULL || in->term_count != 1 || in->terms[0].kind != HD_WRENCH) {
        PyErr_SetString(PyExc_ValueError, "drives: the inputs must be one wrench term");
        return -1;
    }
    const long rows = in->terms[0].count;
    static const struct { const char *what; char format; int writable; } columns[5] = {
        {"drives: ints", 'l', 1}, {"drives: reals", 'd', 1}, {"drives: row_unit", 'l', 0},
        {"drives: row_rates", 'd', 0}, {"drives: steady", 'd', 0}};
    const Py_ssize_t counts[5] = {-1, -1, rows, 3 * rows, units};
    for (int k = 0; k < 5; ++k) {
        if (hd_get_buffer(PyTuple_GET_ITEM(object, k), &views->views[k], columns[k].what,
                          columns[k].format, counts[k], columns[k].writable) < 0) {
            hd_release_drives(views);
            return -1;
        }
        views->held = k + 1;
    }
    const Py_ssize_t count = views->views[0].len / 8 / HD_DRIVE_INTS;
    d->count = (long)count;
    d->ints = views->views[0].buf;
    d->reals = views->views[1].buf;
    d->rows = rows;
    d->row_unit = views->views[2].buf;
    d->row_rates = views->views[3].buf;
    d->steady = views->views[4].buf;
    d->start_ns = PyLong_AsLong(PyTuple_GET_ITEM(object, 5));
    d->step_ns = PyLong_AsLong(PyTuple_GET_ITEM(object, 6));
    d->context = PyTuple_GET_ITEM(object, 7);
    d->hypot = hd_call_hypot;
    d->h = h;
    d->failed = 0;
    int ok = !PyErr_Occurred() && count >= 1 && count <= HD_DRIVE_MOST &&
        views->views[0].len == count * 8 * HD_DRIVE_INTS &&
        views->views[1].len == count * 8 * HD_DRIVE_REALS && d->step_ns > 0 &&
        PyCallable_Check(d->context);
    for (long k = 0; ok && k < d->count; ++k) {  /* instants on the step grid, after now */
        long *i = d->ints + k * HD_DRIVE_INTS;
        ok = i[HD_DRIVE_BODY] >= 0 && i[HD_DRIVE_BODY] < bodies
            && i[HD_DRIVE_PERIOD_NS] >= d->step_ns && i[HD_DRIVE_PERIOD_NS] % d->step_ns == 0
            && i[HD_DRIVE_ROW_LEFT] >= 0 && i[HD_DRIVE_ROW_LEFT] < rows
            && i[HD_DRIVE_ROW_RIGHT] >= 0 && i[HD_DRIVE_ROW_RIGHT] < rows
            && i[HD_DRIVE_NEXT_NS] > d->start_ns
            && (i[HD_DRIVE_NEXT_NS] - d->start_ns) % d->step_ns == 0;
        i[HD_DRIVE_INSTANTS] = 0;
    }
    for (long row = 0; ok && row < rows; ++row)
        ok = d->row_unit[row] >= 0 && d->row_unit[row] < units;
    if (!ok) {
        hd_release_drives(views);
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "drives: columns out of range");
        return -1;
    }
    return 0;
}

PyDoc_STRVAR(run_doc,
"run(stepper, inputs, oriented, q, v, qs, vs, first, steps, size, first_seconds,\n"
"    drives=None)\n"
"    -> (status, taken, evaluations, substeps, rejected, size, checked, worst)\n\n"
"``steps`` (int) steps of the Stepper ``stepper``'s ``h`` from (q, v) (read only;\n"
"C-contiguous float64 of 3 values per body) as ``step`` takes them, without a joint pass,\n"
"with the energy bound's check on the stepper's data (``bound``'s, given to ``stepper``)\n"
"at each publish instant: after ``first`` steps (over ``first_seconds`` s) and every\n"
"``per`` steps after it (over ``period_seconds`` s). Segment k between instants steps in\n"
"row k of (qs, vs), C-contiguous float64 of 3 values per body per segment, from a copy of\n"
"the row before. Stops at the first failing step (``status`` as ``step``'s; the last good\n"
"state ends row (segments begun - 1)) or after the first check over 1. ``inputs``,\n"
"``oriented``, ``size``: as ``step``'s; ``checked``: the checks made, ``worst``: their\n"
"largest ratio of excess to limit. ``drives`` (None: none): the differential drives whose\n"
"wheels are every row of ``inputs``, as src/kernel/drive.h lays them out: a tuple (ints,\n"
"reals, row_unit, row_rates, steady, start_ns, step_ns, hypot), ``start_ns`` the sim time\n"
"now; their instants after the start and before the end are taken inside the run (their\n"
"columns written, the instants counted from 0), which ends at one it leaves to Python.");

static PyObject *hd_py_run(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                           PyObject *kwnames)
{
    static const char *const names[] = {"stepper", "inputs", "oriented", "q", "v", "qs", "vs",
                                        "first", "steps", "size", "first_seconds", "drives",
                                        NULL};
    PyObject *given[12];
    hd_program *in;
    int oriented;
    hd_stepper_capsule *c = hd_get_stepping("run", args, nargs, kwnames, names, 12, 11, given, &in,
                                            &oriented);
    if (c == NULL)
        return NULL;
    hd_stepper *s = &c->stepper;
    const hd_run_bound *b = &c->run;
    const long n = s->program->bodies, n3 = 3 * n;
    const long first = PyLong_AsLong(given[7]), steps = PyLong_AsLong(given[8]);
    double size = PyFloat_AsDouble(given[9]);
    const double first_seconds = PyFloat_AsDouble(given[10]);
    if (PyErr_Occurred())
        return NULL;
    if (b->per < 1) {
        PyErr_SetString(PyExc_ValueError, "run: a stepper built without the energy bound's "
                                          "budget takes no runs");
        return NULL;
    }
    if (first < 1 || steps < 0) {
        PyErr_SetString(PyExc_ValueError, "run: first needs at least 1 step");
        return NULL;
    }
    if (s->method != HD_EMBEDDED)
        size = 0.0;
    const long segments = steps <= first ? 1 : 1 + (steps - first + b->per - 1) / b->per;
    Py_buffer qv, vv, qsv, vsv;
    if (hd_get_buffer(given[3], &qv, "q", 'd', n3, 0) < 0)
        return NULL;
    if (hd_get_buffer(given[4], &vv, "v", 'd', n3, 0) < 0) {
        PyBuffer_Release(&qv);
        return NULL;
    }
    if (hd_get_state(given[5], given[6], segments * n3, &qsv, &vsv) < 0) {
        PyBuffer_Release(&qv);
        PyBuffer_Release(&vv);
        return NULL;
    }
    hd_drives drive_data;
    hd_drives *drives = NULL;
    hd_drive_views drive_views = {.held = 0};
    if (given[11] != NULL && given[11] != Py_None) {
        if (hd_get_drives(given[11], in, b->units, n, b->h, &drive_data, &drive_views) < 0) {
            PyBuffer_Release(&qv);
            PyBuffer_Release(&vv);
            PyBuffer_Release(&qsv);
            PyBuffer_Release(&vsv);
            return NULL;
        }
        drives = &drive_data;
    }
    long taken = 0, checked = 0;
    double worst = 0.0;
    hd_work work = {0, 0, 0};
    int status = HD_OUT_OF_MEMORY;
    double *memory = malloc((size_t)(2 * n + 1 + b->units) * sizeof(double));
    if (drives != NULL)
        drives->rates = memory + 2 * n + 1;
    if (memory != NULL && steps * n < HD_GIL_WORK && s->contacts == NULL) {
        status = hd_run_segments(s, b, in, drives, oriented, &size, qv.buf, vv.buf, qsv.buf,
                                 vsv.buf, first, steps, first_seconds, memory, &taken, &work,
                                 &checked, &worst);
    } else if (memory != NULL) {
        Py_BEGIN_ALLOW_THREADS
        status = hd_run_segments(s, b, in, drives, oriented, &size, qv.buf, vv.buf, qsv.buf,
                                 vsv.buf, first, steps, first_seconds, memory, &taken, &work,
                                 &checked, &worst);
        Py_END_ALLOW_THREADS
    }
    free(memory);
    hd_release_drives(&drive_views);
    PyBuffer_Release(&qv);
    PyBuffer_Release(&vv);
    PyBuffer_Release(&qsv);
    PyBuffer_Release(&vsv);
    if (status == HD_OUT_OF_MEMORY)
        return PyErr_NoMemory();
    return Py_BuildValue("illlldld", status, taken, work.evaluations, work.substeps,
                         work.rejected, size, checked, worst);
}

PyDoc_STRVAR(failed_state_doc,
"failed_state(stepper, q, v)\n\n"
"Copy the state that ended the Stepper ``stepper``'s last ``step`` with NOT_FINITE into\n"
"``q`` and ``v``, C-contiguous float64 of 3 values per body: (x, y, angle) and (vx, vy,\n"
"omega) of each CM.");

/* failed_state and step_start: copy a state the stepper keeps, the failed one or the last
 * step's start (`start`), into the caller's (q, v); `format` names the function. */
static PyObject *hd_give_state(PyObject *args, PyObject *kwargs, const char *format, int start)
{
    static char *names[] = {"stepper", "q", "v", NULL};
    PyObject *capsule, *qo, *vo;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, format, names, &capsule, &qo, &vo))
        return NULL;
    hd_stepper_capsule *c = PyCapsule_GetPointer(capsule, HD_STEPPER_CAPSULE);
    if (c == NULL)
        return NULL;
    const double *q = start ? c->stepper.start_q : c->stepper.q_new,
                 *v = start ? c->stepper.start_v : c->stepper.v_new;
    if (q == NULL) {
        PyErr_SetString(PyExc_ValueError, "step_start: the stepper keeps no starts "
                                          "(keep_starts)");
        return NULL;
    }
    const Py_ssize_t n3 = 3 * c->stepper.program->bodies;
    Py_buffer qv, vv;
    if (hd_get_state(qo, vo, n3, &qv, &vv) < 0)
        return NULL;
    memcpy(qv.buf, q, (size_t)n3 * sizeof(double));
    memcpy(vv.buf, v, (size_t)n3 * sizeof(double));
    PyBuffer_Release(&qv);
    PyBuffer_Release(&vv);
    Py_RETURN_NONE;
}

static PyObject *hd_py_failed_state(PyObject *self, PyObject *args, PyObject *kwargs)
{
    return hd_give_state(args, kwargs, "OOO:failed_state", 0);
}

PyDoc_STRVAR(keep_starts_doc,
"keep_starts(stepper)\n\n"
"From now on, have the Stepper ``stepper`` keep the state that each call's last step of\n"
"``step`` or ``run`` started from, for ``step_start``.");

static PyObject *hd_py_keep_starts(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"stepper", NULL};
    PyObject *capsule;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "O:keep_starts", names, &capsule))
        return NULL;
    hd_stepper_capsule *c = PyCapsule_GetPointer(capsule, HD_STEPPER_CAPSULE);
    if (c == NULL)
        return NULL;
    if (hd_stepper_keep_starts(&c->stepper) != HD_ADVANCED)
        return PyErr_NoMemory();
    Py_RETURN_NONE;
}

PyDoc_STRVAR(step_start_doc,
"step_start(stepper, q, v)\n\n"
"Copy the state the last step of the Stepper ``stepper``'s last call of ``step`` or ``run``\n"
"that took one started from into ``q`` and ``v`` (as ``failed_state`` does); the stepper\n"
"must keep them (``keep_starts``).");

static PyObject *hd_py_step_start(PyObject *self, PyObject *args, PyObject *kwargs)
{
    return hd_give_state(args, kwargs, "OOO:step_start", 1);
}

PyMethodDef hd_bind_stepper[] = {
    {"stepper", (PyCFunction)(void (*)(void))hd_py_stepper, METH_VARARGS | METH_KEYWORDS,
     stepper_doc},
    {"step", (PyCFunction)(void (*)(void))hd_py_step, METH_FASTCALL | METH_KEYWORDS, step_doc},
    {"run", (PyCFunction)(void (*)(void))hd_py_run, METH_FASTCALL | METH_KEYWORDS, run_doc},
    {"failed_state", (PyCFunction)(void (*)(void))hd_py_failed_state,
     METH_VARARGS | METH_KEYWORDS, failed_state_doc},
    {"keep_starts", (PyCFunction)(void (*)(void))hd_py_keep_starts,
     METH_VARARGS | METH_KEYWORDS, keep_starts_doc},
    {"step_start", (PyCFunction)(void (*)(void))hd_py_step_start,
     METH_VARARGS | METH_KEYWORDS, step_start_doc},
    {NULL, NULL, 0, NULL},
};
