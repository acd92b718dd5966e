/* Compiled estimate CSV rows: estimate_csv.ROW_FORMAT % row, for a batch of rows at once.
 *
 * Why: the replay formats one row of ~29 numbers per 6 ms step; Python's %-formatting of them is
 * ~4 us a row, a noticeable share of a replay. The numbers are converted by the function
 * %-formatting itself calls (PyOS_double_to_string, 'f' with 6 digits, 'g' with 9), so the text
 * is the same by construction (a float column whose bits repeat the row before reuses that
 * row's text); "%d" of an int is its decimal digits. Anything else (an int too
 * wide, "%d" of a float, an object that is neither int nor float, a field of more than 62
 * characters) returns NotImplemented and estimate_csv formats in Python; tests/test_estimate_csv.py
 * checks both give the same text on random and special values. Ahead-of-time compiled
 * (setup.py), optional.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

enum { F_FIXED6 = 0, F_INT = 1, F_G9 = 2 };

/* the last text of a float column: a third of the numbers repeat the row before (learned
 * parameters, bank and grade, latency), and the same bits give the same text */
typedef struct {
    int have;
    uint64_t bits;
    size_t len;
    char text[64];
} Memo;

/* "%lld" of v into out (at most cap bytes, no terminator), its length; -1 if it does not fit.
 * Why not snprintf: a third of the fields are ints (validity flags, status, counts) and libc's
 * snprintf was ~1000 instructions each, 40 % of the formatter's time; the digits of an integer
 * are the same whoever writes them (tests/test_estimate_csv.py: random and extreme values) */
static int put_int(char *out, size_t cap, long long v)
{
    char tmp[24];
    int i = (int)sizeof tmp;
    /* the magnitude as unsigned: -LLONG_MIN does not fit a long long */
    unsigned long long m = v < 0 ? 0ULL - (unsigned long long)v : (unsigned long long)v;
    do {
        tmp[--i] = (char)('0' + (int)(m % 10U));
        m /= 10U;
    } while (m);
    if (v < 0)
        tmp[--i] = '-';
    int n = (int)sizeof tmp - i;
    if ((size_t)n >= cap)
        return -1;
    memcpy(out, tmp + i, (size_t)n);
    return n;
}

/* append one field; 0 ok, 1 NotImplemented */
static int put_field(char *buf, size_t cap, size_t *len, int kind, PyObject *o, Memo *memo)
{
    int n;
    if (kind == F_INT) {
        if (!PyLong_Check(o))  /* bools are ints; floats and others: Python */
            return 1;
        int overflow = 0;
        long long v = PyLong_AsLongLongAndOverflow(o, &overflow);
        if (overflow || (v == -1 && PyErr_Occurred())) {
            PyErr_Clear();
            return 1;
        }
        n = put_int(buf + *len, cap - *len, v);
    } else {
        double v;
        if (PyFloat_Check(o)) {
            v = PyFloat_AS_DOUBLE(o);
        } else if (PyLong_Check(o)) {
            v = PyLong_AsDouble(o);
            if (v == -1.0 && PyErr_Occurred()) {
                PyErr_Clear();
                return 1;
            }
        } else {
            return 1;
        }
        uint64_t bits;
        memcpy(&bits, &v, sizeof bits);
        if (memo->have && memo->bits == bits) {
            if (memo->len >= cap - *len)
                return 1;
            memcpy(buf + *len, memo->text, memo->len);
            *len += memo->len;
            return 0;
        }
        /* Python's own conversion (what %-formatting calls): the same text by construction */
        char *s = PyOS_double_to_string(v, kind == F_FIXED6 ? 'f' : 'g', kind == F_FIXED6 ? 6 : 9, 0, NULL);
        if (s == NULL) {
            PyErr_Clear();
            return 1;
        }
        size_t sl = strlen(s);
        if (sl >= cap - *len) {
            PyMem_Free(s);
            return 1;
        }
        memcpy(buf + *len, s, sl);
        PyMem_Free(s);
        if (sl < sizeof memo->text) {
            memo->have = 1;
            memo->bits = bits;
            memo->len = sl;
            memcpy(memo->text, buf + *len, sl);
        }
        n = (int)sl;
    }
    if (n < 0 || (size_t)n >= cap - *len)
        return 1;
    *len += (size_t)n;
    return 0;
}

/* format_rows(kinds: bytes, rows: list[tuple]) -> str | NotImplemented */
static PyObject *f_format_rows(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 2 || !PyBytes_Check(args[0]) || !PyList_Check(args[1])) {
        PyErr_SetString(PyExc_TypeError, "format_rows(kinds: bytes, rows: list)");
        return NULL;
    }
    const unsigned char *kinds = (const unsigned char *)PyBytes_AS_STRING(args[0]);
    Py_ssize_t nf = PyBytes_GET_SIZE(args[0]);
    PyObject *rows = args[1];
    Py_ssize_t nr = PyList_GET_SIZE(rows);
    /* a field longer than 62 chars ("%.6f" of a huge t) goes to Python */
    size_t cap = (size_t)nr * (size_t)nf * 64 + 1;
    char *buf = PyMem_Malloc(cap);
    if (buf == NULL)
        return PyErr_NoMemory();
    Memo *memo = PyMem_Calloc((size_t)nf + 1, sizeof(Memo));
    if (memo == NULL) {
        PyMem_Free(buf);
        return PyErr_NoMemory();
    }
    size_t len = 0;
    for (Py_ssize_t r = 0; r < nr; r++) {
        PyObject *row = PyList_GET_ITEM(rows, r);
        if (!PyTuple_Check(row) || PyTuple_GET_SIZE(row) != nf)
            goto fallback;
        for (Py_ssize_t i = 0; i < nf; i++) {
            /* each field gets 64 chars of its own, separator included: the buffer holds them all */
            if (put_field(buf, len + 63, &len, kinds[i], PyTuple_GET_ITEM(row, i), &memo[i]))
                goto fallback;
            buf[len++] = i + 1 < nf ? ',' : '\n';
        }
    }
    PyObject *out = PyUnicode_DecodeASCII(buf, (Py_ssize_t)len, NULL);
    PyMem_Free(memo);
    PyMem_Free(buf);
    return out;
fallback:
    PyMem_Free(memo);
    PyMem_Free(buf);
    Py_RETURN_NOTIMPLEMENTED;
}

static PyMethodDef methods[] = {
    {"format_rows", (PyCFunction)(void (*)(void))f_format_rows, METH_FASTCALL,
     "format_rows(kinds, rows): ''.join(ROW_FORMAT % row for row in rows), or NotImplemented"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_estimate_csv", "Compiled estimate CSV rows (see _estimate_csv.c).", -1, methods,
};

PyMODINIT_FUNC PyInit__estimate_csv(void)
{
    return PyModule_Create(&module);
}
