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
 * lines() is the other direction: the replay's output frames as candump -L text (see below).
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

/* lines(channel: str, steps: list[(t: float, frames: list[(id: int, payload: bytes | bytearray)])])
 *   -> str | NotImplemented
 *
 * The candump -L text CandumpWriter.write_payloads writes for each step, "(%.6f) CHANNEL %03X#HEX\n"
 * per frame: the time through Python's own float formatting (PyOS_double_to_string, 'f', 6 --
 * what f"{t:.6f}" calls), ids of 11 bits, payloads of up to 64 bytes in uppercase hex. Anything
 * else (a float subclass's own __format__ is not followed either: only exact floats) returns
 * NotImplemented and the caller formats in Python. Why: the replay writes ~2 frames per 6 ms
 * step, and the f-strings were ~3 us a step. */
static PyObject *f_lines(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    static const char hex[] = "0123456789ABCDEF";
    if (nargs != 2 || !PyUnicode_Check(args[0]) || !PyList_Check(args[1])) {
        PyErr_SetString(PyExc_TypeError, "lines(channel: str, steps: list)");
        return NULL;
    }
    Py_ssize_t clen;
    const char *chan = PyUnicode_AsUTF8AndSize(args[0], &clen);
    if (chan == NULL)
        return NULL;
    for (Py_ssize_t i = 0; i < clen; i++)
        if ((unsigned char)chan[i] > 0x7E || (unsigned char)chan[i] <= 0x20)
            Py_RETURN_NOTIMPLEMENTED;
    PyObject *steps = args[1];
    size_t cap = 4096, len = 0;
    char *buf = PyMem_Malloc(cap);
    if (buf == NULL)
        return PyErr_NoMemory();
    for (Py_ssize_t k = 0; k < PyList_GET_SIZE(steps); k++) {
        PyObject *st = PyList_GET_ITEM(steps, k);
        if (!PyTuple_Check(st) || PyTuple_GET_SIZE(st) != 2 || !PyFloat_CheckExact(PyTuple_GET_ITEM(st, 0))
                || !PyList_Check(PyTuple_GET_ITEM(st, 1)))
            goto fallback;
        PyObject *frames = PyTuple_GET_ITEM(st, 1);
        Py_ssize_t nf = PyList_GET_SIZE(frames);
        if (nf == 0)
            continue;
        char *ts = PyOS_double_to_string(PyFloat_AS_DOUBLE(PyTuple_GET_ITEM(st, 0)), 'f', 6, 0, NULL);
        if (ts == NULL) {
            PyMem_Free(buf);
            return NULL;
        }
        size_t tlen = strlen(ts);
        for (Py_ssize_t i = 0; i < nf; i++) {
            PyObject *fr = PyList_GET_ITEM(frames, i);
            if (!PyTuple_Check(fr) || PyTuple_GET_SIZE(fr) != 2 || !PyLong_CheckExact(PyTuple_GET_ITEM(fr, 0))) {
                PyMem_Free(ts);
                goto fallback;
            }
            PyObject *d = PyTuple_GET_ITEM(fr, 1);
            const unsigned char *p;
            Py_ssize_t n;
            if (PyByteArray_Check(d)) {
                p = (const unsigned char *)PyByteArray_AS_STRING(d);
                n = PyByteArray_GET_SIZE(d);
            } else if (PyBytes_Check(d)) {
                p = (const unsigned char *)PyBytes_AS_STRING(d);
                n = PyBytes_GET_SIZE(d);
            } else {
                PyMem_Free(ts);
                goto fallback;
            }
            int overflow = 0;
            long fid = PyLong_AsLongAndOverflow(PyTuple_GET_ITEM(fr, 0), &overflow);
            if (overflow || fid < 0 || fid > 0x7FF || n > 64) {
                PyMem_Free(ts);
                goto fallback;
            }
            size_t need = tlen + (size_t)clen + 2 * (size_t)n + 10;
            if (len + need > cap) {
                size_t ncap = 2 * (len + need);
                char *nb = PyMem_Realloc(buf, ncap);
                if (nb == NULL) {
                    PyMem_Free(ts);
                    PyMem_Free(buf);
                    return PyErr_NoMemory();
                }
                buf = nb;
                cap = ncap;
            }
            buf[len++] = '(';
            memcpy(buf + len, ts, tlen);
            len += tlen;
            buf[len++] = ')';
            buf[len++] = ' ';
            memcpy(buf + len, chan, (size_t)clen);
            len += (size_t)clen;
            buf[len++] = ' ';
            buf[len++] = hex[(fid >> 8) & 0xF];
            buf[len++] = hex[(fid >> 4) & 0xF];
            buf[len++] = hex[fid & 0xF];
            buf[len++] = '#';
            for (Py_ssize_t j = 0; j < n; j++) {
                buf[len++] = hex[p[j] >> 4];
                buf[len++] = hex[p[j] & 0xF];
            }
            buf[len++] = '\n';
        }
        PyMem_Free(ts);
    }
    PyObject *out = PyUnicode_DecodeASCII(buf, (Py_ssize_t)len, NULL);
    PyMem_Free(buf);
    return out;
fallback:
    PyMem_Free(buf);
    Py_RETURN_NOTIMPLEMENTED;
}

static PyMethodDef methods[] = {
    {"parse", (PyCFunction)(void (*)(void))f_parse, METH_FASTCALL,
     "parse(text, channel): (times, ids, flags, data, channels) of a candump -L log's common lines, or None"},
    {"lines", (PyCFunction)(void (*)(void))f_lines, METH_FASTCALL,
     "lines(channel, steps): the candump -L text of [(t, [(id, payload), ...]), ...], or NotImplemented"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_candump", "candump -L logs parsed in one pass, output lines formatted in one (see _candump.c).", -1, methods,
};

PyMODINIT_FUNC PyInit__candump(void)
{
    return PyModule_Create(&module);
}
