/* Compiled packing of output frames: outputs._pack_reference's loop, in C.
 *
 * Why: the output encoder packs ~4 frames of ~10 signals at every 6 ms step; in Python the loop
 * (a dict look-up, a subtraction, a division, round() and a shift per signal) is most of the
 * encoding cost. Same math, same results (tests/test_outputs.py checks both against cantools'
 * Message.encode): round((v - offset) / scale), half to even (nearbyint in the default rounding
 * mode, as Python's round), the raw range check, two's complement bits under the mask. Only for
 * signals of up to 52 bits in up to 8 bytes (a double holds every raw value, a uint64 the
 * payload); anything else returns NotImplemented and the reference packs it.
 * Ahead-of-time compiled (setup.py), optional: outputs.py falls back to the reference.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

/* pack(layout, values, length) -> bytearray | None | NotImplemented
 * layout: tuple of (name, offset, scale, shift, mask, lo, hi); values: dict name -> int | float. */
static PyObject *f_pack(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3 || !PyTuple_Check(args[0]) || !PyDict_Check(args[1])) {
        PyErr_SetString(PyExc_TypeError, "pack(layout: tuple, values: dict, length: int)");
        return NULL;
    }
    PyObject *layout = args[0], *values = args[1];
    Py_ssize_t length = PyLong_AsSsize_t(args[2]);
    if (length == -1 && PyErr_Occurred())
        return NULL;
    if (length < 0 || length > 8)
        Py_RETURN_NOTIMPLEMENTED;
    uint64_t acc = 0;
    Py_ssize_t n = PyTuple_GET_SIZE(layout);
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *entry = PyTuple_GET_ITEM(layout, i);
        if (!PyTuple_Check(entry) || PyTuple_GET_SIZE(entry) != 7) {
            PyErr_SetString(PyExc_TypeError, "pack: layout entries are 7-tuples");
            return NULL;
        }
        PyObject *v_obj = PyDict_GetItemWithError(values, PyTuple_GET_ITEM(entry, 0));
        if (v_obj == NULL) {
            if (!PyErr_Occurred())
                PyErr_SetObject(PyExc_KeyError, PyTuple_GET_ITEM(entry, 0));
            return NULL;
        }
        double v = PyFloat_AsDouble(v_obj);
        double offset = PyFloat_AsDouble(PyTuple_GET_ITEM(entry, 1));
        double scale = PyFloat_AsDouble(PyTuple_GET_ITEM(entry, 2));
        long shift = PyLong_AsLong(PyTuple_GET_ITEM(entry, 3));
        unsigned long long mask = PyLong_AsUnsignedLongLong(PyTuple_GET_ITEM(entry, 4));
        double lo = PyFloat_AsDouble(PyTuple_GET_ITEM(entry, 5));
        double hi = PyFloat_AsDouble(PyTuple_GET_ITEM(entry, 6));
        if (PyErr_Occurred())
            return NULL;
        if (mask >> 52 || shift < 0 || shift >= 64)
            Py_RETURN_NOTIMPLEMENTED;
        double x = (v - offset) / scale;
        if (isnan(x)) {  /* what round() says */
            PyErr_SetString(PyExc_ValueError, "cannot convert float NaN to integer");
            return NULL;
        }
        if (isinf(x)) {
            PyErr_SetString(PyExc_OverflowError, "cannot convert float infinity to integer");
            return NULL;
        }
        double raw = nearbyint(x);
        if (raw < lo || raw > hi)
            Py_RETURN_NONE;
        acc |= ((uint64_t)(int64_t)raw & (uint64_t)mask) << shift;
    }
    if (length < 8 && (acc >> (8 * length)) != 0) {
        PyErr_SetString(PyExc_OverflowError, "int too big to convert");
        return NULL;
    }
    char buf[8];
    for (Py_ssize_t b = 0; b < length; b++)
        buf[b] = (char)((acc >> (8 * b)) & 0xFF);
    return PyByteArray_FromStringAndSize(buf, length);
}

static PyMethodDef methods[] = {
    {"pack", (PyCFunction)(void (*)(void))f_pack, METH_FASTCALL,
     "pack(layout, values, length): the payload of outputs._pack_reference, or None"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_frames", "Compiled packing of output frames (see _frames.c).", -1, methods,
};

PyMODINIT_FUNC PyInit__frames(void)
{
    return PyModule_Create(&module);
}
