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
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

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

/* ---------------------------------------------------------------------------------------------
 * encode(plan, est, counter) -> bytearray | NotImplemented
 *
 * Why: outputs.OutputEncoder.frames built each estimate frame in Python (range check of every
 * field, validity and status bits, pack, E2E CRC): ~25 us of a 6 ms step for 4 frames. This is the
 * same sequence, on a plan compiled once per message (compile_plan). A non-finite or saturated
 * value is replaced and its validity bit cleared as there, when the estimate does not claim it
 * valid; whenever the Python path would do more -- log such a value claimed valid, let cantools
 * encode a raw value outside its bits, read a number that is not a float -- this returns
 * NotImplemented and outputs.py runs its reference path for the frame (tests/test_outputs.py
 * checks both give the same frames on every step of a drive).
 */
enum { K_ZERO = 0, K_COUNTER = 1, K_FIELD = 2, K_VALID = 3, K_STATUS = 4 };
enum { M_SAT = 0, M_ANGLE = 1, M_WRAP = 2 };  /* outputs._SAT, _ANGLE, _WRAP */

typedef struct {
    int kind, mode;
    Py_ssize_t src;         /* K_FIELD: Estimate index; K_VALID: flag index or -1; K_STATUS: status index */
    double lo, hi;          /* K_FIELD: physical range (M_ANGLE: wrap limit hi) */
    long long modulus;      /* M_WRAP */
    long long status_mask;  /* K_STATUS */
    double zero;            /* K_FIELD: stand-in for a non-finite value */
    Py_ssize_t vslot;       /* K_FIELD: the entry of its validity signal, or -1 */
    Py_ssize_t vflag;       /* K_FIELD: that validity signal's Estimate flag, or -1 (none) */
    double offset, scale, rlo, rhi;
    int shift;
    uint64_t mask;
} sig_t;

typedef struct {
    Py_ssize_t n, length;
    int data_id;
    unsigned char crc[256];
    sig_t sig[];
} plan_t;

#define PLAN_CAPSULE "ecu_daemon._frames.plan"

static void plan_free(PyObject *cap)
{
    PyMem_Free(PyCapsule_GetPointer(cap, PLAN_CAPSULE));
}

/* compile_plan(entries, length, data_id, crc_table) -> capsule | None
 * entries: per layout signal (kind, mode, src, lo, hi, modulus, status_mask, zero, validity entry,
 * validity flag, offset, scale, shift, mask, raw lo, raw hi); None when the message does not fit (then outputs.py keeps its reference path). */
static PyObject *f_compile_plan(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4 || !PyTuple_Check(args[0]) || !PyBytes_Check(args[3]) || PyBytes_GET_SIZE(args[3]) != 256) {
        PyErr_SetString(PyExc_TypeError, "compile_plan(entries: tuple, length: int, data_id: int, crc_table: bytes[256])");
        return NULL;
    }
    Py_ssize_t n = PyTuple_GET_SIZE(args[0]);
    Py_ssize_t length = PyLong_AsSsize_t(args[1]);
    long data_id = PyLong_AsLong(args[2]);
    if (PyErr_Occurred())
        return NULL;
    if (length < 1 || length > 8)
        Py_RETURN_NONE;
    plan_t *plan = PyMem_Malloc(sizeof(plan_t) + (size_t)n * sizeof(sig_t));
    if (plan == NULL)
        return PyErr_NoMemory();
    plan->n = n;
    plan->length = length;
    plan->data_id = (int)(data_id & 0xFF);
    memcpy(plan->crc, PyBytes_AS_STRING(args[3]), 256);
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *e = PyTuple_GET_ITEM(args[0], i);
        if (!PyTuple_Check(e) || PyTuple_GET_SIZE(e) != 16) {
            PyMem_Free(plan);
            PyErr_SetString(PyExc_TypeError, "compile_plan: entries are 16-tuples");
            return NULL;
        }
        sig_t *s = &plan->sig[i];
        s->kind = (int)PyLong_AsLong(PyTuple_GET_ITEM(e, 0));
        s->mode = (int)PyLong_AsLong(PyTuple_GET_ITEM(e, 1));
        s->src = PyLong_AsSsize_t(PyTuple_GET_ITEM(e, 2));
        s->lo = PyFloat_AsDouble(PyTuple_GET_ITEM(e, 3));
        s->hi = PyFloat_AsDouble(PyTuple_GET_ITEM(e, 4));
        s->modulus = PyLong_AsLongLong(PyTuple_GET_ITEM(e, 5));
        s->status_mask = PyLong_AsLongLong(PyTuple_GET_ITEM(e, 6));
        s->zero = PyFloat_AsDouble(PyTuple_GET_ITEM(e, 7));
        s->vslot = PyLong_AsSsize_t(PyTuple_GET_ITEM(e, 8));
        s->vflag = PyLong_AsSsize_t(PyTuple_GET_ITEM(e, 9));
        s->offset = PyFloat_AsDouble(PyTuple_GET_ITEM(e, 10));
        s->scale = PyFloat_AsDouble(PyTuple_GET_ITEM(e, 11));
        long shift = PyLong_AsLong(PyTuple_GET_ITEM(e, 12));
        unsigned long long mask = PyLong_AsUnsignedLongLong(PyTuple_GET_ITEM(e, 13));
        s->rlo = PyFloat_AsDouble(PyTuple_GET_ITEM(e, 14));
        s->rhi = PyFloat_AsDouble(PyTuple_GET_ITEM(e, 15));
        if (PyErr_Occurred()) {
            PyMem_Free(plan);
            return NULL;
        }
        if (mask >> 52 || shift < 0 || shift >= 64 || s->kind < K_ZERO || s->kind > K_STATUS
            || s->vslot >= n || (s->kind == K_FIELD && s->mode != M_WRAP && s->vslot < 0)
            || (s->kind == K_FIELD && (s->mode < M_SAT || s->mode > M_WRAP || s->src < 0
                                       || (s->mode == M_WRAP && s->modulus <= 0)))) {
            PyMem_Free(plan);
            Py_RETURN_NONE;
        }
        s->shift = (int)shift;
        s->mask = (uint64_t)mask;
    }
    PyObject *cap = PyCapsule_New(plan, PLAN_CAPSULE, plan_free);
    if (cap == NULL)
        PyMem_Free(plan);
    return cap;
}

/* Python's float % float (floatobject.c float_rem): the result takes the divisor's sign. */
static double py_fmod(double v, double w)
{
    double mod = fmod(v, w);
    if (mod != 0.0) {
        if ((w < 0) != (mod < 0))
            mod += w;
    } else {
        mod = copysign(0.0, w);
    }
    return mod;
}

/* int(v) % modulus for a finite number; 0 on success, -1: leave it to Python. */
static int wrap_value(PyObject *o, long long modulus, double *out)
{
    long long iv;
    if (PyLong_Check(o)) {
        int overflow = 0;
        iv = PyLong_AsLongLongAndOverflow(o, &overflow);
        if (overflow || (iv == -1 && PyErr_Occurred())) {
            PyErr_Clear();
            return -1;
        }
    } else if (PyFloat_Check(o)) {
        double d = PyFloat_AS_DOUBLE(o);
        if (!isfinite(d)) {
            *out = 0.0;
            return 0;
        }
        if (!(fabs(d) < 9.0e18))
            return -1;
        iv = (long long)d;  /* truncation toward zero, as int() */
    } else {
        return -1;
    }
    long long r = iv % modulus;
    if (r < 0)
        r += modulus;
    *out = (double)r;
    return 0;
}

/* A value the reference path would replace and mark invalid (saturated, not finite): fine here when
 * the estimate does not claim it valid (no log line then); 0 done, 1 leave it to Python, -1 error. */
static int clear_valid(const sig_t *s, PyObject *est, Py_ssize_t nest, unsigned char *ok)
{
    if (s->vflag < 0 || s->vflag >= nest)
        return 1;  /* claimed while the filter runs: outputs._claimed decides, and logs */
    int claimed = PyObject_IsTrue(PyTuple_GET_ITEM(est, s->vflag));
    if (claimed < 0)
        return -1;
    if (claimed)
        return 1;
    ok[s->vslot] = 0;
    return 0;
}

#define MAX_SIGNALS 64

static PyObject *f_encode(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3 || !PyTuple_Check(args[1])) {
        PyErr_SetString(PyExc_TypeError, "encode(plan, est: tuple, counter: int)");
        return NULL;
    }
    plan_t *plan = PyCapsule_GetPointer(args[0], PLAN_CAPSULE);
    if (plan == NULL)
        return NULL;
    PyObject *est = args[1];
    Py_ssize_t nest = PyTuple_GET_SIZE(est);
    long counter = PyLong_AsLong(args[2]);
    if (counter == -1 && PyErr_Occurred())
        return NULL;
    Py_ssize_t n = plan->n;
    if (n > MAX_SIGNALS)
        Py_RETURN_NOTIMPLEMENTED;
    double val[MAX_SIGNALS];
    unsigned char ok[MAX_SIGNALS];
    memset(ok, 1, sizeof ok);
    /* pass 1: the fields (outputs.OutputEncoder._fill), which may clear validity */
    for (Py_ssize_t i = 0; i < n; i++) {
        const sig_t *s = &plan->sig[i];
        if (s->kind != K_FIELD)
            continue;
        if (s->src >= nest)
            Py_RETURN_NOTIMPLEMENTED;
        PyObject *o = PyTuple_GET_ITEM(est, s->src);
        double v;
        if (s->mode == M_WRAP) {
            if (wrap_value(o, s->modulus, &v) < 0)
                Py_RETURN_NOTIMPLEMENTED;
            val[i] = v;
            continue;
        }
        if (!PyFloat_Check(o))  /* ints, bools, anything else: the reference path */
            Py_RETURN_NOTIMPLEMENTED;
        v = PyFloat_AS_DOUBLE(o);
        if (!isfinite(v)) {
            int r = clear_valid(s, est, nest, ok);
            if (r < 0)
                return NULL;
            if (r > 0)
                Py_RETURN_NOTIMPLEMENTED;
            v = s->zero;
        } else if (s->mode == M_ANGLE) {
            v = py_fmod(v, 2.0 * M_PI);
            if (v >= s->hi)
                v = 0.0;
        } else if (v < s->lo || v > s->hi) {
            int r = clear_valid(s, est, nest, ok);
            if (r < 0)
                return NULL;
            if (r > 0)
                Py_RETURN_NOTIMPLEMENTED;
            v = v < s->lo ? s->lo : s->hi;
        }
        val[i] = v;
    }
    /* pass 2: validity and status bits, the counter, then pack */
    uint64_t acc = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        const sig_t *s = &plan->sig[i];
        double v;
        switch (s->kind) {
        case K_ZERO:
            v = 0.0;
            break;
        case K_COUNTER:
            v = (double)counter;
            break;
        case K_VALID:
            if (!ok[i]) {
                v = 0.0;
            } else if (s->src < 0) {
                v = 1.0;
            } else {
                if (s->src >= nest)
                    Py_RETURN_NOTIMPLEMENTED;
                int truth = PyObject_IsTrue(PyTuple_GET_ITEM(est, s->src));
                if (truth < 0)
                    return NULL;
                v = truth ? 1.0 : 0.0;
            }
            break;
        case K_STATUS: {
            if (s->src >= nest || !PyLong_Check(PyTuple_GET_ITEM(est, s->src)))
                Py_RETURN_NOTIMPLEMENTED;
            long long st = PyLong_AsLongLong(PyTuple_GET_ITEM(est, s->src));
            if (st == -1 && PyErr_Occurred()) {
                PyErr_Clear();
                Py_RETURN_NOTIMPLEMENTED;
            }
            v = (st & s->status_mask) ? 1.0 : 0.0;
            break;
        }
        default:
            v = val[i];
        }
        double raw = nearbyint((v - s->offset) / s->scale);
        if (!(raw >= s->rlo && raw <= s->rhi))
            Py_RETURN_NOTIMPLEMENTED;
        acc |= ((uint64_t)(int64_t)raw & s->mask) << s->shift;
    }
    Py_ssize_t length = plan->length;
    if (length < 8 && (acc >> (8 * length)) != 0)
        Py_RETURN_NOTIMPLEMENTED;
    unsigned char buf[8];
    for (Py_ssize_t b = 0; b < length; b++)
        buf[b] = (unsigned char)((acc >> (8 * b)) & 0xFF);
    /* E2E profile 2 (integrity.e2e_p2_crc): CRC8H2F over bytes 1.. and the data id, into byte 0 */
    const unsigned char *t = plan->crc;
    unsigned r = 0xFF;
    for (Py_ssize_t b = 1; b < length; b++)
        r = t[r ^ buf[b]];
    buf[0] = (unsigned char)(t[r ^ (unsigned)plan->data_id] ^ 0xFF);
    return PyByteArray_FromStringAndSize((const char *)buf, length);
}

/* e2e_p2(payload, data_id, crc_table) -> int | NotImplemented: integrity.e2e_p2_crc in C, for the
 * frames the Python path encodes (the EST_DIAG pages: every other step; ~1 us in Python). A data id
 * outside 0..255 returns NotImplemented (the reference then decides what that means). */
static PyObject *f_e2e_p2(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3 || !PyByteArray_Check(args[0]) || !PyLong_Check(args[1]) || !PyBytes_Check(args[2])
        || PyBytes_GET_SIZE(args[2]) != 256) {
        PyErr_SetString(PyExc_TypeError, "e2e_p2(payload: bytearray, data_id: int, crc_table: bytes[256])");
        return NULL;
    }
    int overflow = 0;
    long id = PyLong_AsLongAndOverflow(args[1], &overflow);
    if (id == -1 && PyErr_Occurred())
        return NULL;
    if (overflow || id < 0 || id > 255)
        Py_RETURN_NOTIMPLEMENTED;
    const unsigned char *t = (const unsigned char *)PyBytes_AS_STRING(args[2]);
    const unsigned char *b = (const unsigned char *)PyByteArray_AS_STRING(args[0]);
    Py_ssize_t n = PyByteArray_GET_SIZE(args[0]);
    unsigned r = 0xFF;
    for (Py_ssize_t i = 1; i < n; i++)
        r = t[r ^ b[i]];
    return PyLong_FromLong((long)(t[r ^ (unsigned)id] ^ 0xFF));
}

static PyMethodDef methods[] = {
    {"e2e_p2", (PyCFunction)(void (*)(void))f_e2e_p2, METH_FASTCALL,
     "e2e_p2(payload, data_id, crc_table): integrity.e2e_p2_crc of a bytearray, or NotImplemented"},
    {"pack", (PyCFunction)(void (*)(void))f_pack, METH_FASTCALL,
     "pack(layout, values, length): the payload of outputs._pack_reference, or None"},
    {"compile_plan", (PyCFunction)(void (*)(void))f_compile_plan, METH_FASTCALL,
     "compile_plan(entries, length, data_id, crc_table): an estimate frame's plan for encode(), or None"},
    {"encode", (PyCFunction)(void (*)(void))f_encode, METH_FASTCALL,
     "encode(plan, est, counter): the frame's payload with its CRC, or NotImplemented (reference path)"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_frames", "Compiled packing of output frames (see _frames.c).", -1, methods,
};

PyMODINIT_FUNC PyInit__frames(void)
{
    return PyModule_Create(&module);
}
