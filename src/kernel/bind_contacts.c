/* The binding of the contact pass (contact.h) for hecker_dynamics/contact/compiled.py:
 * contacts, resolve, threads, sleep and warm, each taking keyword arguments.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bind.h"
#include "contact.h"
#include "coupled.h"
#include "joint.h"
#include "wide.h"

static void hd_contacts_destructor(PyObject *capsule)
{
    hd_contact_model *m = PyCapsule_GetPointer(capsule, HD_CONTACTS_CAPSULE);
    if (m != NULL)
        hd_coupled_free(m->coupled);
    hd_contact_free(m);
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

/* The map's boxes from the packed rows (kind, count) and their values in the fixed frame;
 * -1 with an exception set if they are not polygons of that many values or a body that
 * collides with them or is swept is out of range. */
static int hd_build_statics(hd_contact_model *m, const long *static_ints,
                            Py_ssize_t static_ints_count, const double *reals,
                            Py_ssize_t real_count)
{
    Py_ssize_t used = 0;
    if (2 * m->static_count != static_ints_count)
        goto bad;
    for (long k = 0; k < m->static_count; ++k) {
        if (static_ints[2 * k] != HD_POLYGON || static_ints[2 * k + 1] < 3)
            goto bad;
        used += 4 * static_ints[2 * k + 1];
    }
    for (long k = 0; k < m->static_body_count; ++k)
        if (m->static_body[k] < 0 || m->static_body[k] >= m->bodies)
            goto bad;
    for (long k = 0; k < m->swept_count; ++k)
        if (m->swept[k] < 0 || m->swept[k] >= m->bodies)
            goto bad;
    if (used != real_count)
        goto bad;
    m->statics = calloc((size_t)m->static_count + 1, sizeof(hd_part));
    if (m->statics == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    for (long k = 0; k < m->static_count; ++k) {
        hd_part *part = m->statics + k;
        part->kind = HD_POLYGON;
        part->count = static_ints[2 * k + 1];
        part->placed = malloc(4 * (size_t)part->count * sizeof(double));
        if (part->placed == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        memcpy(part->placed, reals, 4 * (size_t)part->count * sizeof(double));
        reals += 4 * part->count;
        if (part->count > m->max_vertices)
            m->max_vertices = part->count;
    }
    return 0;
bad:
    PyErr_SetString(PyExc_ValueError, "static_ints, static_reals, static_bodies or swept: not "
                    "the layout of contact.h");
    return -1;
}

PyDoc_STRVAR(contacts_doc,
"contacts(inverse_mass, inverse_inertia, reach, part_ints, part_reals, walls, wall_first,\n"
"         wall_body, colliding, classes, class_groups, materials, apart, threshold,\n"
"         thickness, static_ints, static_reals, static_bounds, static_material,\n"
"         static_bodies, swept, slop, converged, lead) -> Contacts\n\n"
"A scene's contact pass (contact.h): per body its inverse mass and inertia and reach;\n"
"per part (body, kind, vertex count) sorted by body, with its values in body axes; per\n"
"wall (nx, ny, offset, restitution, friction) and its bodies; the colliding bodies; per\n"
"body its class, per pair of classes their group, per group (restitution, friction), and\n"
"the pairs (i, j), sorted, that do not collide (contact/materials.py: PairMaterials);\n"
"per map box (kind, vertex count), its vertices and normals in the fixed frame and its\n"
"bounds (x0, x1, y0, y1), the boxes' (restitution, friction) and the bodies that collide\n"
"with them; the bodies whose travel sets the sub-steps; per body its slop; the velocity\n"
"passes' tolerance (contacts.converged, positive: they stop once no impulse changes a\n"
"velocity by more than it relative to the island's fastest body, contact/solve.py); the\n"
"bounce's share of the step's change of the normal velocity (contact/solver.py:\n"
"ContactPass.follow, finite).");

static PyObject *hd_py_contacts(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"inverse_mass", "inverse_inertia", "reach", "part_ints",
                            "part_reals", "walls", "wall_first", "wall_body", "colliding",
                            "classes", "class_groups", "materials", "apart", "threshold",
                            "thickness", "static_ints", "static_reals", "static_bounds",
                            "static_material", "static_bodies", "swept", "slop", "converged", "lead",
                            NULL};
    PyObject *o[20];
    double threshold, thickness, converged, lead;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOOOOOOOOOOddOOOOOOOdd:contacts", names,
                                     o, o + 1, o + 2, o + 3, o + 4, o + 5, o + 6, o + 7, o + 8,
                                     o + 9, o + 10, o + 11, o + 12, &threshold, &thickness,
                                     o + 13, o + 14, o + 15, o + 16, o + 17, o + 18, o + 19,
                                     &converged, &lead))
        return NULL;
    if (!(converged > 0.0 && isfinite(converged))) {
        PyErr_SetString(PyExc_ValueError, "contacts: converged must be positive and finite");
        return NULL;
    }
    if (!isfinite(lead)) {
        PyErr_SetString(PyExc_ValueError, "contacts: lead must be finite");
        return NULL;
    }
    hd_contact_model *m = calloc(1, sizeof(hd_contact_model));
    if (m == NULL)
        return PyErr_NoMemory();
    Py_ssize_t bodies, parts, reals, walls, wall_bodies, colliding, cells, materials, apart,
        statics, static_reals, static_bodies, swept;
    long *part_ints = NULL, *static_ints = NULL;
    double *part_reals = NULL, *static_values = NULL, *static_material = NULL;
    m->threshold = threshold;
    m->thickness = thickness;
    m->converged = converged;
    m->lead = lead;
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
        (m->apart = hd_read_array(o[12], "apart", 'q', -1, &apart)) == NULL ||
        (static_ints = hd_read_array(o[13], "static_ints", 'q', -1, &statics)) == NULL ||
        (static_values = hd_read_array(o[14], "static_reals", 'd', -1, &static_reals)) == NULL ||
        (m->static_bounds = hd_read_array(o[15], "static_bounds", 'd', 2 * statics,
                                          NULL)) == NULL ||
        (static_material = hd_read_array(o[16], "static_material", 'd', 2, NULL)) == NULL ||
        (m->static_body = hd_read_array(o[17], "static_bodies", 'q', -1, &static_bodies)) == NULL ||
        (m->swept = hd_read_array(o[18], "swept", 'q', -1, &swept)) == NULL ||
        (m->slop = hd_read_array(o[19], "slop", 'd', bodies, NULL)) == NULL)
        goto fail;
    m->static_material[0] = static_material[0];
    m->static_material[1] = static_material[1];
    m->static_count = (long)(statics / 2);
    m->static_body_count = (long)static_bodies;
    m->swept_count = (long)swept;
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
    if (hd_build_parts(m, part_ints, part_reals) < 0) {
        PyErr_NoMemory();
        goto fail;
    }
    if (hd_build_statics(m, static_ints, statics, static_values, static_reals) < 0)
        goto fail;
    if (hd_contact_prepare(m) < 0) {
        PyErr_NoMemory();
        goto fail;
    }
    free(part_ints);
    free(part_reals);
    free(static_ints);
    free(static_values);
    free(static_material);
    PyObject *capsule = PyCapsule_New(m, HD_CONTACTS_CAPSULE, hd_contacts_destructor);
    if (capsule == NULL)
        hd_contact_free(m);
    return capsule;
fail:
    free(part_ints);
    free(part_reals);
    free(static_ints);
    free(static_values);
    free(static_material);
    hd_contact_free(m);
    return NULL;
}

PyDoc_STRVAR(resolve_doc,
"resolve(contacts, q1, v1, q0, v0, h, joints=None)\n\n"
"The contact pass after a step of ``h`` (s) from (q0, v0) to (q1, v1) (ContactPass.resolve):\n"
"``contacts`` the pass (contacts()); ``q1`` and ``v1`` the step's end state, (x, y, angle)\n"
"and (vx, vy, omega) of each CM, C-contiguous float64, updated in place; ``q0`` and ``v0``\n"
"the step's start, where sleeping bodies go back to; ``joints`` the joint pass (joints(),\n"
"or None) whose last velocity rows are solved with the contacts.");

static PyObject *hd_py_resolve(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                               PyObject *kwnames)
{
    static const char *const names[] = {"contacts", "q1", "v1", "q0", "v0", "h", "joints",
                                        NULL};
    PyObject *given[7];
    hd_contact_model *m = hd_capsule_arguments("resolve", args, nargs, kwnames, names, 7,
                                               6, HD_CONTACTS_CAPSULE, given);
    if (m == NULL)
        return NULL;
    PyObject *const *objects = given + 1;
    PyObject *joints_object = given[6] != NULL ? given[6] : Py_None;
    const double h = PyFloat_AsDouble(given[5]);
    if (h == -1.0 && PyErr_Occurred())
        return NULL;
    hd_joint_model *joints = NULL;
    if (joints_object != Py_None) {
        if ((joints = PyCapsule_GetPointer(joints_object, HD_JOINTS_CAPSULE)) == NULL)
            return NULL;
        for (long k = 0; k < joints->body_count; ++k)
            if (joints->bodies[k] >= m->bodies) {
                PyErr_SetString(PyExc_ValueError, "resolve: a joint pass for other bodies");
                return NULL;
            }
    }
    Py_buffer views[4];
    for (int k = 0; k < 4; ++k) {
        if (hd_get_buffer(objects[k], views + k, names[k + 1], 'd', 3 * m->bodies, k < 2) < 0) {
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

PyDoc_STRVAR(threads_doc,
"threads(contacts, *, count=None) -> (count, started)\n\n"
"The threads of the velocity passes of big islands of the pass ``contacts`` (1 or 2, the\n"
"same bits either way; wide.h), first set to ``count`` if given, and whether the second\n"
"thread was started.");

static PyObject *hd_py_threads(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                               PyObject *kwnames)
{
    static const char *const names[] = {"contacts", "count", NULL};
    PyObject *given[2];
    hd_contact_model *m = hd_capsule_arguments("threads", args, nargs, kwnames, names, 1,
                                               1, HD_CONTACTS_CAPSULE, given);
    if (m == NULL)
        return NULL;
    PyObject *count_object = given[1];
    if (count_object != NULL && count_object != Py_None) {
        const long count = PyLong_AsLong(count_object);
        if (count == -1 && PyErr_Occurred())
            return NULL;
        if (count < 1 || count > 2) {
            PyErr_Format(PyExc_ValueError, "threads: 1 or 2, not %ld", count);
            return NULL;
        }
        m->threads = (int)count;
    }
    return Py_BuildValue("(iO)", m->threads, m->crew != NULL ? Py_True : Py_False);
}

PyDoc_STRVAR(sleep_doc,
"sleep(contacts, *, enabled=None, calm=None, rested=None, island=None) -> (rested, island)\n\n"
"Sleeping of resting islands (ContactPass._doze) in the pass ``contacts``: per body its\n"
"rest time (s) and sleeping island (-1: awake). Given all four keywords, first set them:\n"
"``enabled`` whether resting islands sleep, and per body (C-contiguous) ``calm`` whether it\n"
"may sleep (int64 0 or 1), ``rested`` its rest time (float64), ``island`` its sleeping\n"
"island (int64, -1: awake).");

static PyObject *hd_py_sleep(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                             PyObject *kwnames)
{
    static const char *const names[] = {"contacts", "enabled", "calm", "rested", "island",
                                        NULL};
    PyObject *given[5];
    hd_contact_model *m = hd_capsule_arguments("sleep", args, nargs, kwnames, names, 1,
                                               1, HD_CONTACTS_CAPSULE, given);
    if (m == NULL)
        return NULL;
    PyObject *const *objects = given + 2;
    const int settings = (given[1] != NULL) + (objects[0] != NULL) + (objects[1] != NULL) +
                         (objects[2] != NULL);
    if (settings != 0 && settings != 4) {
        PyErr_SetString(PyExc_TypeError, "sleep: give enabled, calm, rested and island "
                        "together, or none");
        return NULL;
    }
    if (settings) {
        const int enabled = PyObject_IsTrue(given[1]);
        if (enabled < 0)
            return NULL;
        Py_buffer views[3];
        const char kinds[3] = {'q', 'd', 'q'};
        for (int k = 0; k < 3; ++k) {
            if (hd_get_buffer(objects[k], views + k, names[k + 2], kinds[k], m->bodies, 0) < 0) {
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
"warm(contacts, *, impulses=None) -> list\n\n"
"The impulses the pass ``contacts`` keeps for warm starting, as (k0, k1, k2, k3, lx, ly,\n"
"jn, jt) per contact: the key of its pair of parts (k0..k3), its point in body b's axes and\n"
"its normal and tangent impulses, those of one pair of parts together and in the order the\n"
"solver met them; given ``impulses`` (a sequence of such tuples), replace them first.");

static PyObject *hd_py_warm(PyObject *self, PyObject *const *args, Py_ssize_t nargs,
                            PyObject *kwnames)
{
    static const char *const names[] = {"contacts", "impulses", NULL};
    PyObject *given[2];
    hd_contact_model *m = hd_capsule_arguments("warm", args, nargs, kwnames, names, 1,
                                               1, HD_CONTACTS_CAPSULE, given);
    if (m == NULL)
        return NULL;
    PyObject *impulses = given[1] != NULL ? given[1] : Py_None;
    if (impulses != Py_None) {
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

PyMethodDef hd_bind_contacts[] = {
    {"contacts", (PyCFunction)(void (*)(void))hd_py_contacts, METH_VARARGS | METH_KEYWORDS,
     contacts_doc},
    {"resolve", (PyCFunction)(void (*)(void))hd_py_resolve, METH_FASTCALL | METH_KEYWORDS,
     resolve_doc},
    {"warm", (PyCFunction)(void (*)(void))hd_py_warm, METH_FASTCALL | METH_KEYWORDS, warm_doc},
    {"sleep", (PyCFunction)(void (*)(void))hd_py_sleep, METH_FASTCALL | METH_KEYWORDS,
     sleep_doc},
    {"threads", (PyCFunction)(void (*)(void))hd_py_threads, METH_FASTCALL | METH_KEYWORDS,
     threads_doc},
    {NULL, NULL, 0, NULL},
};
