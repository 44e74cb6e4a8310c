/* The one loop Python cannot run fast enough: Embree's packet query over a buffer of ray packets.
 *
 * embreex binds only rtcIntersect1 (one ray a call). Embree's 16-ray packets with the coherent flag cast
 * the bake's texel rays (4x4 tiles from one origin) about twice as fast, but a call per packet from Python
 * costs as much as the packet itself and holds the GIL. This module calls Embree's packet function (its
 * address, from ctypes) once per packet, for n packets `stride` bytes apart, with the GIL released, so
 * that threads cast in parallel. Everything else (the scene, the packet layout, the threads) is Python:
 * geometry/_embree_packets.py. Built by setuptools as an optional extension: without a C compiler it is
 * missing and the Embree caster casts one ray at a time through embreex.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

typedef void (*packet_fn)(const int *valid, void *scene, void *rayhit, void *args);

static PyObject *cast(PyObject *self, PyObject *a) {
    unsigned long long fn, valid, scene, buf, args;
    Py_ssize_t n, stride;
    if (!PyArg_ParseTuple(a, "KKKKnnK", &fn, &valid, &scene, &buf, &n, &stride, &args)) return NULL;
    if (!fn || !valid || !scene || !buf || n < 0 || stride <= 0) {
        PyErr_SetString(PyExc_ValueError, "cast: null pointer, negative count or non-positive stride");
        return NULL;
    }
    packet_fn f = (packet_fn)(uintptr_t)fn;
    char *p = (char *)(uintptr_t)buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < n; i++) f((const int *)(uintptr_t)valid, (void *)(uintptr_t)scene, p + i * stride, (void *)(uintptr_t)args);
    Py_END_ALLOW_THREADS
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"cast", cast, METH_VARARGS,
     "cast(fn, valid, scene, buf, n, stride, args): fn(valid, scene, buf + i * stride, args) for i < n, "
     "the GIL released (fn: the address of Embree's rtcIntersect16 or rtcOccluded16)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_packet_loop", NULL, -1, methods};

PyMODINIT_FUNC PyInit__packet_loop(void) { return PyModule_Create(&module); }
