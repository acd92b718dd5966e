/* A candump -L log's common lines parsed in one pass: canlog.CanLogReader's result, in C.
 *
 * Why: replay reads every frame of a log before its first step (can_arrays.py); through the
 * regex reader that is ~1.5 us a frame, a tenth of the replay. This takes only the lines every
 * recorder writes -- "(secs.frac) iface ID#HEXDATA", 3 or 8 hex digits of id, up to 8 data bytes,
 * optional " R"/" T" -- with the reader's checks (11-bit id <= 0x7FF, 29-bit id <= 0x1FFFFFFF, an
 * error frame's id), and the time through Python's own float() (PyOS_string_to_double), so the
 * values are the reader's. Anything else (comments, blank lines, remote or CAN FD frames, dotted
 * data, a line the reader refuses) returns None, and can_arrays.py reads the log with the reader,
 * which handles it or names the bad line. Ahead-of-time compiled (setup.py), optional.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>
#include <math.h>

#define CAN_ERR_FLAG 0x20000000u
#define CAN_EFF_MASK 0x1FFFFFFFu

static int hexval(unsigned char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

static int is_space(unsigned char c) { return c == ' ' || c == '\t'; }

/* parse(text: bytes, channel: str | None) -> (times: bytes(float64), ids: bytes(int64),
 *   flags: bytes(uint8: 1 extended, 2 error frame), data: list[bytes], channels: dict) | None */
static PyObject *f_parse(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 2 || !PyBytes_Check(args[0]) || (args[1] != Py_None && !PyUnicode_Check(args[1]))) {
        PyErr_SetString(PyExc_TypeError, "parse(text: bytes, channel: str | None)");
        return NULL;
    }
    const char *buf = PyBytes_AS_STRING(args[0]);
    Py_ssize_t size = PyBytes_GET_SIZE(args[0]);
    const char *want = NULL;
    Py_ssize_t want_len = 0;
    if (args[1] != Py_None) {
        want = PyUnicode_AsUTF8AndSize(args[1], &want_len);
        if (want == NULL)
            return NULL;
    }
    Py_ssize_t cap = 1024, n = 0;
    double *times = PyMem_Malloc(cap * sizeof(double));
    int64_t *ids = PyMem_Malloc(cap * sizeof(int64_t));
    unsigned char *flags = PyMem_Malloc(cap);
    PyObject *data = PyList_New(0), *channels = PyDict_New(), *result = NULL;
    PyObject *last_name = NULL;  /* the previous line's channel name (most logs have one) */
    char tsbuf[64];
    if (!times || !ids || !flags || !data || !channels)
        goto fail;
    Py_ssize_t i = 0;
    while (i < size) {
        Py_ssize_t e = i;
        while (e < size && buf[e] != '\n')
            e++;
        Py_ssize_t end = e;  /* the line is buf[i:end] (without its newline) */
        if (end > i && buf[end - 1] == '\r')
            end--;
        Py_ssize_t p = i;
        while (p < end && is_space((unsigned char)buf[p]))
            p++;
        if (p >= end || buf[p] != '(')
            goto fallback;
        Py_ssize_t ts0 = ++p, dot = -1;
        while (p < end && ((buf[p] >= '0' && buf[p] <= '9') || (buf[p] == '.' && dot < 0))) {
            if (buf[p] == '.')
                dot = p;
            p++;
        }
        if (dot < 0 || dot == ts0 || p == dot + 1 || p >= end || buf[p] != ')' || p - ts0 >= (Py_ssize_t)sizeof tsbuf)
            goto fallback;
        memcpy(tsbuf, buf + ts0, p - ts0);
        tsbuf[p - ts0] = 0;
        p++;
        if (p >= end || !is_space((unsigned char)buf[p]))
            goto fallback;
        while (p < end && is_space((unsigned char)buf[p]))
            p++;
        Py_ssize_t if0 = p;
        while (p < end && !is_space((unsigned char)buf[p]) && (unsigned char)buf[p] > ' ' && (unsigned char)buf[p] < 0x7F)
            p++;
        Py_ssize_t if1 = p;
        if (if1 == if0 || p >= end || !is_space((unsigned char)buf[p]))
            goto fallback;
        while (p < end && is_space((unsigned char)buf[p]))
            p++;
        Py_ssize_t id0 = p;
        uint64_t can_id = 0;
        while (p < end && hexval((unsigned char)buf[p]) >= 0) {
            can_id = (can_id << 4) | (uint64_t)hexval((unsigned char)buf[p]);
            p++;
            if (p - id0 > 8)
                goto fallback;
        }
        Py_ssize_t id_len = p - id0;
        if ((id_len != 3 && id_len != 8) || p >= end || buf[p] != '#')
            goto fallback;
        p++;
        Py_ssize_t d0 = p;
        while (p < end && hexval((unsigned char)buf[p]) >= 0)
            p++;
        Py_ssize_t d_len = p - d0;
        if (d_len % 2 || d_len > 16)
            goto fallback;
        /* what may follow: [ \t]+[RT] then [ \t]* */
        Py_ssize_t q = p;
        while (q < end && is_space((unsigned char)buf[q]))
            q++;
        if (q < end) {
            if (q == p || (buf[q] != 'R' && buf[q] != 'T'))
                goto fallback;
            q++;
            while (q < end && is_space((unsigned char)buf[q]))
                q++;
            if (q < end)
                goto fallback;
        }
        unsigned char fl = 0;
        if (id_len == 3) {
            if (can_id > 0x7FF)
                goto fallback;
        } else if (can_id & CAN_ERR_FLAG) {
            if (can_id & ~(uint64_t)(CAN_ERR_FLAG | CAN_EFF_MASK))
                goto fallback;
            can_id &= CAN_EFF_MASK;
            fl = 2;
        } else if (can_id > CAN_EFF_MASK) {
            goto fallback;
        } else {
            fl = 1;
        }
        /* the channel: counted whether kept or not */
        PyObject *name;
        if (last_name != NULL && PyUnicode_GET_LENGTH(last_name) == if1 - if0
            && memcmp(PyUnicode_DATA(last_name), buf + if0, if1 - if0) == 0) {
            name = last_name;
            Py_INCREF(name);
        } else {
            name = PyUnicode_DecodeASCII(buf + if0, if1 - if0, "strict");
            if (name == NULL)
                goto fail;
            Py_XDECREF(last_name);
            last_name = name;
            Py_INCREF(last_name);
        }
        PyObject *count = PyDict_GetItemWithError(channels, name);
        long long c = 0;
        if (count == NULL && PyErr_Occurred()) {
            Py_DECREF(name);
            goto fail;
        }
        if (count != NULL)
            c = PyLong_AsLongLong(count);
        PyObject *c1 = PyLong_FromLongLong(c + 1);
        if (c1 == NULL || PyDict_SetItem(channels, name, c1) < 0) {
            Py_XDECREF(c1);
            Py_DECREF(name);
            goto fail;
        }
        Py_DECREF(c1);
        Py_DECREF(name);
        if (want != NULL && (if1 - if0 != want_len || memcmp(buf + if0, want, want_len) != 0)) {
            i = e + 1;
            continue;
        }
        double t = PyOS_string_to_double(tsbuf, NULL, NULL);
        if (t == -1.0 && PyErr_Occurred()) {
            PyErr_Clear();
            goto fallback;
        }
        if (!isfinite(t))
            goto fallback;
        unsigned char bytes[8];
        for (Py_ssize_t b = 0; b < d_len / 2; b++)
            bytes[b] = (unsigned char)(hexval((unsigned char)buf[d0 + 2 * b]) << 4 | hexval((unsigned char)buf[d0 + 2 * b + 1]));
        PyObject *payload = PyBytes_FromStringAndSize((const char *)bytes, d_len / 2);
        if (payload == NULL)
            goto fail;
        int rc = PyList_Append(data, payload);
        Py_DECREF(payload);
        if (rc < 0)
            goto fail;
        if (n == cap) {
            cap *= 2;
            double *t2 = PyMem_Realloc(times, cap * sizeof(double));
            if (t2 == NULL)
                goto fail;
            times = t2;
            int64_t *i2 = PyMem_Realloc(ids, cap * sizeof(int64_t));
            if (i2 == NULL)
                goto fail;
            ids = i2;
            unsigned char *f2 = PyMem_Realloc(flags, cap);
            if (f2 == NULL)
                goto fail;
            flags = f2;
        }
        times[n] = t;
        ids[n] = (int64_t)can_id;
        flags[n] = fl;
        n++;
        i = e + 1;
    }
    result = Py_BuildValue("(y#y#y#OO)", (const char *)times, (Py_ssize_t)(n * sizeof(double)), (const char *)ids,
                           (Py_ssize_t)(n * sizeof(int64_t)), (const char *)flags, n, data, channels);
    goto done;
fallback:
    result = Py_None;
    Py_INCREF(result);
    goto done;
fail:
    result = NULL;
done:
    PyMem_Free(times);
    PyMem_Free(ids);
    PyMem_Free(flags);
    Py_XDECREF(data);
    Py_XDECREF(channels);
    Py_XDECREF(last_name);
    return result;
}

static PyMethodDef methods[] = {
    {"parse", (PyCFunction)(void (*)(void))f_parse, METH_FASTCALL,
     "parse(text, channel): (times, ids, flags, data, channels) of a candump -L log's common lines, or None"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_candump", "candump -L logs parsed in one pass (see _candump.c).", -1, methods,
};

PyMODINIT_FUNC PyInit__candump(void)
{
    return PyModule_Create(&module);
}
