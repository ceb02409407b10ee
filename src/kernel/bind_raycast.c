/* The binding of the laser ray casts (raycast.h) for hecker_dynamics/sensors/laser.py:
 * laser (keyword arguments), laser_cast (keyword arguments).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdlib.h>

#include "bind.h"
#include "raycast.h"

static void hd_laser_destructor(PyObject *capsule)
{
    hd_laser_free(PyCapsule_GetPointer(capsule, HD_LASER_CAPSULE));
}

/* Each body's first shape in a list of shapes sorted by body (`first`: bodies + 1
 * entries), or -1 if `body` is not sorted or out of range. */
static int hd_firsts(const long *body, Py_ssize_t count, long bodies, long *first)
{
    for (Py_ssize_t k = 0; k < count; ++k)
        if (body[k] < 0 || body[k] >= bodies || (k > 0 && body[k] < body[k - 1]))
            return -1;
    Py_ssize_t k = 0;
    for (long b = 0; b <= bodies; ++b) {
        first[b] = (long)k;
        while (k < count && body[k] == b)
            ++k;
    }
    return 0;
}

PyDoc_STRVAR(laser_doc,
"laser(reach, circle_body, circles, edge_body, edges, walls, range_max) -> Laser\n\n"
"A laser's scene (raycast.h): per body its bounding radius about the CM plus SLACK; per\n"
"circle its body (sorted) and CM-frame (x, y, radius); per polygon edge its body (sorted)\n"
"and CM-frame (start x, y, span x, y); per wall (point x, y, unit normal x, y); the\n"
"range beyond which a hit is no return.");

static PyObject *hd_py_laser(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"reach", "circle_body", "circles", "edge_body", "edges", "walls",
                            "range_max", NULL};
    PyObject *o[6];
    double range_max;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOOOd:laser", names, o, o + 1, o + 2,
                                     o + 3, o + 4, o + 5, &range_max))
        return NULL;
    hd_laser *l = calloc(1, sizeof(hd_laser));
    if (l == NULL)
        return PyErr_NoMemory();
    Py_ssize_t bodies, circles, edges, walls;
    long *circle_body = NULL, *edge_body = NULL;
    if ((l->reach = hd_read_array(o[0], "reach", 'd', -1, &bodies)) == NULL ||
        (circle_body = hd_read_array(o[1], "circle_body", 'q', -1, &circles)) == NULL ||
        (l->circles = hd_read_array(o[2], "circles", 'd', 3 * circles, NULL)) == NULL ||
        (edge_body = hd_read_array(o[3], "edge_body", 'q', -1, &edges)) == NULL ||
        (l->edges = hd_read_array(o[4], "edges", 'd', 4 * edges, NULL)) == NULL ||
        (l->walls = hd_read_array(o[5], "walls", 'd', -1, &walls)) == NULL)
        goto fail;
    l->body_count = (long)bodies;
    l->wall_count = (long)(walls / 4);
    l->range_max = range_max;
    l->circle_first = malloc(((size_t)bodies + 1) * sizeof(long));
    l->edge_first = malloc(((size_t)bodies + 1) * sizeof(long));
    if (l->circle_first == NULL || l->edge_first == NULL) {
        PyErr_NoMemory();
        goto fail;
    }
    if (walls % 4 || hd_firsts(circle_body, circles, l->body_count, l->circle_first) < 0 ||
            hd_firsts(edge_body, edges, l->body_count, l->edge_first) < 0) {
        PyErr_SetString(PyExc_ValueError, "laser: not the layout of raycast.h");
        goto fail;
    }
    if (hd_laser_prepare(l) < 0) {
        PyErr_NoMemory();
        goto fail;
    }
    free(circle_body);
    free(edge_body);
    PyObject *capsule = PyCapsule_New(l, HD_LASER_CAPSULE, hd_laser_destructor);
    if (capsule == NULL)
        hd_laser_free(l);
    return capsule;
fail:
    free(circle_body);
    free(edge_body);
    hd_laser_free(l);
    return NULL;
}

PyDoc_STRVAR(laser_cast_doc,
"laser_cast(laser, q, cos, sin, origin, directions, first, increment, ranges)\n\n"
"sensors/laser.py: cast of the laser's rays at CM state q (N x 3) whose angles have the\n"
"cosines ``cos`` and sines ``sin`` (N each): the distance along each unit direction\n"
"(R x 2) from ``origin`` (2) to its first hit within range_max, +inf for none, into\n"
"``ranges`` (R). Ray k points about ``first`` + k ``increment`` rad.");

static PyObject *hd_py_laser_cast(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *names[] = {"laser", "q", "cos", "sin", "origin", "directions", "first",
                            "increment", "ranges", NULL};
    PyObject *capsule, *o[6];
    double first, increment;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOOOddO:laser_cast", names, &capsule,
                                     o, o + 1, o + 2, o + 3, o + 4, &first, &increment, o + 5))
        return NULL;
    hd_laser *l = PyCapsule_GetPointer(capsule, HD_LASER_CAPSULE);
    if (l == NULL)
        return NULL;
    Py_buffer view[6];
    static const char *what[] = {"q", "cos", "sin", "origin", "directions", "ranges"};
    const Py_ssize_t n = l->body_count;
    Py_ssize_t counts[] = {3 * n, n, n, 2, -1, -1};
    int held = 0;
    for (; held < 6; ++held) {
        if (held == 5)
            counts[5] = view[4].len / 16;
        if (hd_get_buffer(o[held], view + held, what[held], 'd', counts[held], held == 5) < 0)
            break;
    }
    if (held == 6 && view[4].len % 16) {
        PyErr_SetString(PyExc_ValueError, "directions: expected (x, y) pairs");
    } else if (held == 6) {
        const double *origin = view[3].buf;
        hd_laser_cast(l, view[0].buf, view[1].buf, view[2].buf, origin[0], origin[1],
                      view[4].buf, (long)counts[5], first, increment, view[5].buf);
    }
    for (int k = 0; k < held; ++k)
        PyBuffer_Release(view + k);
    if (PyErr_Occurred())
        return NULL;
    Py_RETURN_NONE;
}

PyMethodDef hd_bind_raycast[] = {
    {"laser", (PyCFunction)(void (*)(void))hd_py_laser, METH_VARARGS | METH_KEYWORDS,
     laser_doc},
    {"laser_cast", (PyCFunction)(void (*)(void))hd_py_laser_cast,
     METH_VARARGS | METH_KEYWORDS, laser_cast_doc},
    {NULL, NULL, 0, NULL},
};
