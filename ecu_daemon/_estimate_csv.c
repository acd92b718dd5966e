/* Compiled estimate CSV rows: estimate_csv.ROW_FORMAT % row, for a batch of rows at once.
 *
 * Why: the replay formats one row of ~29 numbers per 6 ms step; Python's %-formatting of them is
 * ~4 us a row, a noticeable share of a replay. A float is converted exactly (fast_float: the
 * correctly rounded digits from 128-bit integers, laid out as Python does) or, where that declines
 * (ties, non-finite, huge or tiny), by the function %-formatting itself calls
 * (PyOS_double_to_string, 'f' with 6 digits, 'g' with 9); a float column whose bits repeat the
 * row before reuses that row's text; "%d" of an int is its decimal digits. Anything else (an int too
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

#ifdef __SIZEOF_INT128__
typedef unsigned __int128 u128;
static const uint64_t POW10[20] = {
    1ULL, 10ULL, 100ULL, 1000ULL, 10000ULL, 100000ULL, 1000000ULL, 10000000ULL, 100000000ULL,
    1000000000ULL, 10000000000ULL, 100000000000ULL, 1000000000000ULL, 10000000000000ULL,
    100000000000000ULL, 1000000000000000ULL, 10000000000000000ULL, 100000000000000000ULL,
    1000000000000000000ULL, 10000000000000000000ULL};

/* round(m * 2**q * 10**k) to an integer, exactly (m < 2**53, q < 0, k <= 19); 0 when the
 * product lies exactly half-way (the caller leaves ties to Python) */
static int scaled_round(uint64_t m, int q, int k, u128 *out)
{
    u128 n = (u128)m * POW10[k];  /* < 2**53 * 10**19 < 2**117: exact */
    int s = -q;
    if (s > 120) {  /* n < 2**117 < half: rounds to 0 */
        *out = 0;
        return 1;
    }
    u128 i = n >> s;
    u128 rem = n - (i << s);
    u128 half = (u128)1 << (s - 1);
    if (rem == half)
        return 0;
    *out = i + (rem > half);
    return 1;
}
#endif

/* "%.9g" (kind F_G9) or "%.6f" (F_FIXED6) of v into out (64 bytes), its length; -1 to leave the
 * number to PyOS_double_to_string. Why: Python's conversion (a dtoa, a malloc'd string) was
 * ~850 instructions a number, half of the formatter's time. Here v = m * 2**q exactly, and
 * round(v * 10**k) is computed in 128-bit integers, so the digits are the correctly rounded ones
 * dtoa gives (half-way cases, non-finite values, |v| >= 2**52 or below ~1e-11 for 'g' go to
 * Python); the layout is Python's format_float_short's for these two formats, without the
 * alternate form. tests/test_estimate_csv.py compares it with %-formatting on random bits, ties
 * and estimate-like values. */
static int fast_float(char *out, double v, int kind)
{
#ifdef __SIZEOF_INT128__
    if (!isfinite(v))
        return -1;
    int len = 0;
    if (signbit(v))
        out[len++] = '-';
    double a = fabs(v);
    if (a == 0.0) {
        if (kind == F_FIXED6) {
            memcpy(out + len, "0.000000", 8);
            return len + 8;
        }
        out[len++] = '0';
        return len;
    }
    int e2;
    double f = frexp(a, &e2);  /* a = f * 2**e2, 0.5 <= f < 1 */
    uint64_t m = (uint64_t)ldexp(f, 53);  /* exact: f has at most 53 significant bits */
    int q = e2 - 53;
    if (q >= 0)  /* |v| >= 2**52 */
        return -1;
    u128 r;
    char dig[40];
    int nd = 0;
    if (kind == F_FIXED6) {
        if (!scaled_round(m, q, 6, &r))
            return -1;
        uint64_t ip = (uint64_t)(r / 1000000U), fp = (uint64_t)(r % 1000000U);
        do {
            dig[nd++] = (char)('0' + (int)(ip % 10U));
            ip /= 10U;
        } while (ip);
        while (nd)
            out[len++] = dig[--nd];
        out[len++] = '.';
        for (int j = 5; j >= 0; j--) {
            out[len + j] = (char)('0' + (int)(fp % 10U));
            fp /= 10U;
        }
        return len + 6;
    }
    /* 'g', 9 significant digits: find k with 10**8 <= round(a * 10**k) < 10**9 */
    int k = 8 - (int)floor((e2 - 1) * 0.30102999566398120);  /* 8 - floor(log10(a)), within 1 */
    uint64_t d9 = 0;
    for (int tries = 0;; tries++) {
        if (tries > 3 || k < 0 || k > 19)
            return -1;
        if (!scaled_round(m, q, k, &r))
            return -1;
        if (r < 100000000U) {
            k++;
        } else if (r > 1000000000U) {
            k--;
        } else if (r == 1000000000U) {  /* 999999999.5 and up: one digit more, 10**8 */
            d9 = 100000000U;
            k--;
            break;
        } else {
            d9 = (uint64_t)r;
            break;
        }
    }
    int decpt = 9 - k;  /* the decimal point after this many digits of d9 */
    for (int j = 8; j >= 0; j--) {
        dig[j] = (char)('0' + (int)(d9 % 10U));
        d9 /= 10U;
    }
    nd = 9;
    while (nd > 1 && dig[nd - 1] == '0')
        nd--;
    if (decpt <= -4 || decpt > 9) {  /* d.ddde+XX */
        out[len++] = dig[0];
        if (nd > 1) {
            out[len++] = '.';
            memcpy(out + len, dig + 1, (size_t)(nd - 1));
            len += nd - 1;
        }
        int e = decpt - 1;
        out[len++] = 'e';
        out[len++] = e < 0 ? '-' : '+';
        if (e < 0)
            e = -e;
        if (e >= 100)
            out[len++] = (char)('0' + e / 100);
        out[len++] = (char)('0' + e / 10 % 10);
        out[len++] = (char)('0' + e % 10);
    } else if (decpt <= 0) {  /* 0.000ddd */
        out[len++] = '0';
        out[len++] = '.';
        for (int j = 0; j < -decpt; j++)
            out[len++] = '0';
        memcpy(out + len, dig, (size_t)nd);
        len += nd;
    } else if (decpt >= nd) {  /* ddd000 */
        memcpy(out + len, dig, (size_t)nd);
        len += nd;
        for (int j = nd; j < decpt; j++)
            out[len++] = '0';
    } else {  /* dd.ddd */
        memcpy(out + len, dig, (size_t)decpt);
        len += decpt;
        out[len++] = '.';
        memcpy(out + len, dig + decpt, (size_t)(nd - decpt));
        len += nd - decpt;
    }
    return len;
#else
    (void)out; (void)v; (void)kind;
    return -1;
#endif
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
        char fast[64];
        int fl = fast_float(fast, v, kind);
        if (fl >= 0) {
            if ((size_t)fl >= cap - *len)
                return 1;
            memcpy(buf + *len, fast, (size_t)fl);
            memo->have = 1;
            memo->bits = bits;
            memo->len = (size_t)fl;
            memcpy(memo->text, fast, (size_t)fl);
            *len += (size_t)fl;
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
