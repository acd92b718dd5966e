/* Compiled estimator kernels: the per-step linear algebra of kinematic.py, kalman.py and
 * history.py on 8x8 float64 arrays, in place, with no Python object created per call.
 *
 * Why: numpy's per-call overhead (~1 us) dominates 8x8 products; the step is a few hundred
 * flops. Ahead-of-time compiled (setup.py, at pip install), no JIT: the service keeps
 * MemoryDenyWriteExecute=yes. The model f and the sparse structure of F come from
 * _generated.h (tools/derive_jacobians.py), the same SymPy derivation as generated.py.
 * Each function is the same math as its *_reference in Python (tests/test_kernels.py checks a
 * whole drive both ways within 1e-9).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#include "_generated.h"

#define N GEN_NX
#define TWO_PI 6.283185307179586

/* A writable C-contiguous float64 buffer of exactly `count` doubles (count < 0: a multiple of -count). */
static double *get_doubles(PyObject *obj, Py_buffer *view, Py_ssize_t count, const char *name)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return NULL;
    Py_ssize_t n = view->len / (Py_ssize_t)sizeof(double);
    if (view->itemsize != sizeof(double) || strcmp(view->format, "d") != 0
        || (count > 0 ? n != count : (n == 0 || n % (-count) != 0))) {
        PyErr_Format(PyExc_ValueError, "%s: expected a contiguous float64 array of %zd values", name,
                     count > 0 ? count : -count);
        PyBuffer_Release(view);
        return NULL;
    }
    return (double *)view->buf;
}

static double py_mod(double a, double m)
{
    double r = fmod(a, m);
    if (r != 0.0) {
        if (r < 0.0)
            r += m;
    } else {
        r = copysign(0.0, m);
    }
    return r;
}

static void symmetrize(double *P)
{
    for (int a = 0; a < N; a++)
        for (int b = 0; b < a; b++) {
            double v = 0.5 * (P[a * N + b] + P[b * N + a]);
            P[a * N + b] = v;
            P[b * N + a] = v;
        }
}

/* 1 if P is finite and positive definite: every pivot of its L D L' factorisation (the
 * Cholesky factor's squared diagonal, without the square roots) is > 0. One division per column
 * and no sqrt: this runs on every stored step a late GNSS fix corrects. */
static int positive_definite(const double *P)
{
    double L[N * N], W[N * N]; /* W = L D (unit lower L, D the pivots) */
    for (int a = 0; a < N * N; a++)
        if (!isfinite(P[a]))
            return 0;
    for (int j = 0; j < N; j++) {
        double d = P[j * N + j];
        for (int k = 0; k < j; k++)
            d -= W[j * N + k] * L[j * N + k];
        if (!(d > 0.0))
            return 0;
        double inv = 1.0 / d;
        for (int i = j + 1; i < N; i++) {
            double w = P[i * N + j];
            for (int k = 0; k < j; k++)
                w -= W[i * N + k] * L[j * N + k];
            W[i * N + j] = w;
            L[i * N + j] = w * inv;
        }
    }
    return 1;
}

/* x <- f(x, u); F's varying entries set; P_out <- F P F' + diag(q), with F = I + (its few
 * off-diagonal entries). The math of predict and predict_from. */
static void predict_core(double *x, const double *P, double *Po, double *F, const double *q,
                         double r_m, double ax_m, double ay_m, double dt)
{
    double fx[GEN_N_MODEL_ROWS], fv[GEN_N_F_VAR], fc[GEN_N_F_CONST];
    gen_kinematic_f(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], r_m, ax_m, ay_m, dt, fx);
    gen_kinematic_F_var(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], r_m, ax_m, ay_m, dt, fv);
    gen_kinematic_F_const(dt, fc);
    for (int m = 0; m < GEN_N_MODEL_ROWS; m++)
        x[GEN_MODEL_ROWS[m]] = fx[m];
    if (x[2] >= TWO_PI || x[2] < 0.0)
        x[2] = py_mod(x[2], TWO_PI);
    /* the sparse part E of F = I + E: (row, col, value) */
    int er[GEN_N_F_CONST + GEN_N_F_VAR], ec[GEN_N_F_CONST + GEN_N_F_VAR];
    double ev[GEN_N_F_CONST + GEN_N_F_VAR];
    int ne = 0;
    for (int m = 0; m < GEN_N_F_CONST; m++, ne++) {
        er[ne] = GEN_F_CONST[m][0];
        ec[ne] = GEN_F_CONST[m][1];
        ev[ne] = fc[m];
    }
    for (int m = 0; m < GEN_N_F_VAR; m++, ne++) {
        er[ne] = GEN_F_VAR[m][0];
        ec[ne] = GEN_F_VAR[m][1];
        ev[ne] = fv[m];
        F[er[ne] * N + ec[ne]] = fv[m];
    }
    double T[N * N];
    memcpy(T, P, sizeof(T)); /* T = F P = P + E P */
    for (int m = 0; m < ne; m++)
        for (int b = 0; b < N; b++)
            T[er[m] * N + b] += ev[m] * P[ec[m] * N + b];
    memcpy(Po, T, sizeof(T)); /* P_out = T F' = T + T E' */
    for (int m = 0; m < ne; m++)
        for (int a = 0; a < N; a++)
            Po[a * N + er[m]] += ev[m] * T[a * N + ec[m]];
    for (int a = 0; a < N; a++)
        Po[a * N + a] += q[a];
}

/* predict(x, P, P_out, F, q, r_m, ax_m, ay_m, dt): x <- f(x, u); F's varying entries set;
 * P_out <- F P F' + diag(q), with F = I + (its few off-diagonal entries). */
static PyObject *k_predict(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 9) {
        PyErr_SetString(PyExc_TypeError, "predict(x, P, P_out, F, q, r_m, ax_m, ay_m, dt)");
        return NULL;
    }
    double r_m = PyFloat_AsDouble(args[5]), ax_m = PyFloat_AsDouble(args[6]);
    double ay_m = PyFloat_AsDouble(args[7]), dt = PyFloat_AsDouble(args[8]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bx, bp, bo, bf, bq;
    double *x = get_doubles(args[0], &bx, N, "x");
    if (!x)
        return NULL;
    double *P = get_doubles(args[1], &bp, N * N, "P");
    if (!P)
        goto fail_x;
    double *Po = get_doubles(args[2], &bo, N * N, "P_out");
    if (!Po)
        goto fail_p;
    double *F = get_doubles(args[3], &bf, N * N, "F");
    if (!F)
        goto fail_o;
    double *q = get_doubles(args[4], &bq, N, "q");
    if (!q)
        goto fail_f;

    predict_core(x, P, Po, F, q, r_m, ax_m, ay_m, dt);

    PyBuffer_Release(&bq);
    PyBuffer_Release(&bf);
    PyBuffer_Release(&bo);
    PyBuffer_Release(&bp);
    PyBuffer_Release(&bx);
    Py_RETURN_NONE;
fail_f:
    PyBuffer_Release(&bf);
fail_o:
    PyBuffer_Release(&bo);
fail_p:
    PyBuffer_Release(&bp);
fail_x:
    PyBuffer_Release(&bx);
    return NULL;
}

/* predict_from(x_prev, x, P_prev, P_out, F, A, q, r_m, ax_m, ay_m, dt): one step from the
 * previous slot into this one: x <- x_prev, then predict (x, P_prev, P_out, F, q, ...), then
 * A <- F. The three calls core.Estimator._step made (two numpy slice copies and predict) in
 * one, with the same arithmetic: the same bits. */
static PyObject *k_predict_from(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 11) {
        PyErr_SetString(PyExc_TypeError, "predict_from(x_prev, x, P_prev, P_out, F, A, q, r_m, ax_m, ay_m, dt)");
        return NULL;
    }
    double r_m = PyFloat_AsDouble(args[7]), ax_m = PyFloat_AsDouble(args[8]);
    double ay_m = PyFloat_AsDouble(args[9]), dt = PyFloat_AsDouble(args[10]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer b[7];
    static const Py_ssize_t counts[7] = {N, N, N * N, N * N, N * N, N * N, N};
    static const char *names[7] = {"x_prev", "x", "P_prev", "P_out", "F", "A", "q"};
    double *p[7];
    int got = 0;
    for (; got < 7; got++) {
        p[got] = get_doubles(args[got], &b[got], counts[got], names[got]);
        if (!p[got])
            break;
    }
    if (got == 7) {
        memcpy(p[1], p[0], N * sizeof(double));
        predict_core(p[1], p[2], p[3], p[4], p[6], r_m, ax_m, ay_m, dt);
        memcpy(p[5], p[4], N * N * sizeof(double));
    }
    for (int m = 0; m < got; m++)
        PyBuffer_Release(&b[m]);
    if (got < 7)
        return NULL;
    Py_RETURN_NONE;
}

/* Joseph-form update with gain K = Ph / S: P <- (I - K h') P (I - K h')' + R K K', given
 * Ph = P h and Bh computed from B = (I - K h') P; x += K y; A <- A - K (h' A). */
static void joseph_update(double *x, double *P, double *A, const double *h, int idx, double y,
                          double R, const double *Ph, double S)
{
    double K[N], Bh[N];
    for (int a = 0; a < N; a++)
        K[a] = Ph[a] / S;
    for (int a = 0; a < N; a++)
        x[a] += K[a] * y;
    for (int a = 0; a < N; a++)
        for (int b = 0; b < N; b++)
            P[a * N + b] -= K[a] * Ph[b];
    for (int a = 0; a < N; a++) {
        if (h) {
            double s = 0.0;
            for (int b = 0; b < N; b++)
                s += P[a * N + b] * h[b];
            Bh[a] = s;
        } else {
            Bh[a] = P[a * N + idx];
        }
    }
    for (int a = 0; a < N; a++)
        for (int b = 0; b < N; b++) {
            P[a * N + b] -= Bh[a] * K[b];
            P[a * N + b] += R * (K[a] * K[b]);
        }
    if (A) {
        double hA[N];
        for (int b = 0; b < N; b++) {
            if (h) {
                double s = 0.0;
                for (int c = 0; c < N; c++)
                    s += h[c] * A[c * N + b];
                hA[b] = s;
            } else {
                hA[b] = A[idx * N + b];
            }
        }
        for (int a = 0; a < N; a++)
            for (int b = 0; b < N; b++)
                A[a * N + b] -= K[a] * hA[b];
    }
}

/* shared argument handling of scalar_update / index_update */
static PyObject *update(PyObject *const *args, Py_ssize_t nargs, int indexed)
{
    const char *sig = indexed ? "index_update(x, P, innovation, i, R, gate_sigma=0.0, A=None)"
                              : "scalar_update(x, P, innovation, h, R, gate_sigma=0.0, A=None)";
    if (nargs < 5 || nargs > 7) {
        PyErr_SetString(PyExc_TypeError, sig);
        return NULL;
    }
    double y = PyFloat_AsDouble(args[2]);
    double R = PyFloat_AsDouble(args[4]);
    double gate = nargs > 5 ? PyFloat_AsDouble(args[5]) : 0.0;
    long idx = indexed ? PyLong_AsLong(args[3]) : 0;
    if (PyErr_Occurred())
        return NULL;
    if (indexed && (idx < 0 || idx >= N)) {
        PyErr_SetString(PyExc_IndexError, "state index out of range");
        return NULL;
    }
    Py_buffer bx, bp, bh, ba;
    int have_h = 0, have_a = 0;
    PyObject *ret = NULL;
    double *x = get_doubles(args[0], &bx, N, "x");
    if (!x)
        return NULL;
    double *P = get_doubles(args[1], &bp, N * N, "P");
    if (!P)
        goto done_x;
    double *h = NULL, *A = NULL;
    if (!indexed) {
        h = get_doubles(args[3], &bh, N, "h");
        if (!h)
            goto done_p;
        have_h = 1;
    }
    if (nargs > 6 && args[6] != Py_None) {
        A = get_doubles(args[6], &ba, N * N, "A");
        if (!A)
            goto done_h;
        have_a = 1;
    }
    double Ph[N], S;
    for (int a = 0; a < N; a++) {
        if (h) {
            double s = 0.0;
            for (int b = 0; b < N; b++)
                s += P[a * N + b] * h[b];
            Ph[a] = s;
        } else {
            Ph[a] = P[a * N + idx];
        }
    }
    if (h) {
        S = 0.0;
        for (int a = 0; a < N; a++)
            S += h[a] * Ph[a];
        S += R;
    } else {
        S = Ph[idx] + R;
    }
    if (!(S > 0.0) || (gate > 0.0 && y * y > gate * gate * S)) {
        ret = Py_False;
    } else {
        joseph_update(x, P, A, h, (int)idx, y, R, Ph, S);
        ret = Py_True;
    }
    Py_INCREF(ret);
    if (have_a)
        PyBuffer_Release(&ba);
done_h:
    if (have_h)
        PyBuffer_Release(&bh);
done_p:
    PyBuffer_Release(&bp);
done_x:
    PyBuffer_Release(&bx);
    return ret;
}

static PyObject *k_scalar_update(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    return update(args, nargs, 0);
}

static PyObject *k_index_update(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    return update(args, nargs, 1);
}

static PyObject *k_symmetrize(PyObject *self, PyObject *arg)
{
    Py_buffer b;
    double *P = get_doubles(arg, &b, N * N, "P");
    if (!P)
        return NULL;
    symmetrize(P);
    PyBuffer_Release(&b);
    Py_RETURN_NONE;
}

/* M = sum_c D[c] u_c u_c' (u_c = U + c * N): a symmetric matrix of rank r <= LOWRANK_MAX, by
 * elimination with symmetric pivoting (the largest remaining |diagonal| first). What a late
 * update takes off the covariance is M = P - Joseph(P) = K S K' (rank = the measurement's
 * dimension, 1 or 2), so carrying U instead of M through the history costs an 8 x r product per
 * step instead of two 8 x 8 ones. Stops when what remains is rounding (every |entry| <= 1e-13 of
 * M's largest); -1 (carry M whole) when the pivot is not the largest entry's size (an indefinite
 * M) or more than LOWRANK_MAX terms would be needed. */
#define LOWRANK_MAX 4
static int lowrank_factor(const double *M, double *U, double *D)
{
    double R[N * N];
    memcpy(R, M, sizeof(R));
    double scale = 0.0;
    for (int a = 0; a < N * N; a++) {
        if (!isfinite(M[a]))
            return -1;
        if (fabs(M[a]) > scale)
            scale = fabs(M[a]);
    }
    for (int r = 0;; r++) {
        double amax = 0.0;
        for (int a = 0; a < N * N; a++)
            if (fabs(R[a]) > amax)
                amax = fabs(R[a]);
        if (amax <= 1e-13 * scale)
            return r;
        if (r == LOWRANK_MAX)
            return -1;
        int p = 0;
        for (int a = 1; a < N; a++)
            if (fabs(R[a * N + a]) > fabs(R[p * N + p]))
                p = a;
        double d = R[p * N + p];
        if (!(fabs(d) >= 0.5 * amax))
            return -1;
        double *u = U + r * N;
        for (int a = 0; a < N; a++)
            u[a] = R[a * N + p] / d;
        D[r] = d;
        for (int a = 0; a < N; a++)
            for (int b = 0; b < N; b++)
                R[a * N + b] -= d * u[a] * u[b];
    }
}

/* correct(X, P, A, s, last, dx, M) -> bool: the history shift of history.py, carried step by step
 * (d_j = A_j d_{j-1}, M_j = A_j M_{j-1} A_j', M_j through its low-rank factor when it has one:
 * lowrank_factor); every corrected P symmetric and checked positive definite before anything is
 * written (False: nothing changed). */
static PyObject *k_correct(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "correct(X, P, A, s, last, dx, M)");
        return NULL;
    }
    long long s = PyLong_AsLongLong(args[3]), last = PyLong_AsLongLong(args[4]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bX, bP, bA, bd, bM;
    PyObject *ret = NULL;
    double *X = get_doubles(args[0], &bX, -N, "X");
    if (!X)
        return NULL;
    Py_ssize_t n = bX.len / (Py_ssize_t)(N * sizeof(double));
    double *P = get_doubles(args[1], &bP, n * N * N, "P");
    if (!P)
        goto r_x;
    double *A = get_doubles(args[2], &bA, n * N * N, "A");
    if (!A)
        goto r_p;
    double *dx = get_doubles(args[5], &bd, N, "dx");
    if (!dx)
        goto r_a;
    double *M0 = get_doubles(args[6], &bM, N * N, "M");
    if (!M0)
        goto r_d;
    long long count = last - s + 1;
    if (count < 1 || count > n) {
        PyErr_SetString(PyExc_ValueError, "correct: step outside the history");
        goto r_m;
    }
    double *newX = PyMem_Malloc((size_t)count * N * sizeof(double));
    double *newP = PyMem_Malloc((size_t)count * N * N * sizeof(double));
    if (!newX || !newP) {
        PyMem_Free(newX);
        PyMem_Free(newP);
        PyErr_NoMemory();
        goto r_m;
    }
    double d[N], M[N * N], T[N * N], U[LOWRANK_MAX * N], D[LOWRANK_MAX];
    memcpy(d, dx, sizeof(d));
    memcpy(M, M0, sizeof(M));
    int rank = count > 1 ? lowrank_factor(M0, U, D) : -1;
    int ok = 1;
    for (long long c = 0; c < count && ok; c++) {
        long long slot = (s + c) % n;
        if (slot < 0)
            slot += n;
        if (c > 0) {
            const double *Ak = A + slot * N * N;
            double d2[N];
            for (int a = 0; a < N; a++) {
                double v = 0.0;
                for (int b = 0; b < N; b++)
                    v += Ak[a * N + b] * d[b];
                d2[a] = v;
            }
            memcpy(d, d2, sizeof(d));
            if (rank >= 0) {
                for (int r = 0; r < rank; r++) { /* u_r = A u_r */
                    double *u = U + r * N, u2[N];
                    for (int a = 0; a < N; a++) {
                        double v = 0.0;
                        for (int b = 0; b < N; b++)
                            v += Ak[a * N + b] * u[b];
                        u2[a] = v;
                    }
                    memcpy(u, u2, sizeof(u2));
                }
                for (int a = 0; a < N; a++) /* M = U D U', lower triangle mirrored */
                    for (int b = 0; b <= a; b++) {
                        double v = 0.0;
                        for (int r = 0; r < rank; r++)
                            v += D[r] * U[r * N + a] * U[r * N + b];
                        M[a * N + b] = v;
                        M[b * N + a] = v;
                    }
            } else {
                for (int a = 0; a < N; a++) /* T = A M */
                    for (int b = 0; b < N; b++) {
                        double v = 0.0;
                        for (int k = 0; k < N; k++)
                            v += Ak[a * N + k] * M[k * N + b];
                        T[a * N + b] = v;
                    }
                for (int a = 0; a < N; a++) /* M = T A', lower triangle mirrored */
                    for (int b = 0; b <= a; b++) {
                        double v = 0.0;
                        for (int k = 0; k < N; k++)
                            v += T[a * N + k] * Ak[b * N + k];
                        M[a * N + b] = v;
                        M[b * N + a] = v;
                    }
            }
        }
        double *xo = newX + c * N, *po = newP + c * N * N;
        const double *xi = X + slot * N, *pi = P + slot * N * N;
        for (int a = 0; a < N; a++)
            xo[a] = xi[a] + d[a];
        for (int a = 0; a < N * N; a++)
            po[a] = pi[a] - M[a];
        symmetrize(po);
        ok = positive_definite(po);
    }
    if (ok) {
        for (long long c = 0; c < count; c++) {
            long long slot = (s + c) % n;
            if (slot < 0)
                slot += n;
            double *xo = newX + c * N;
            xo[2] = py_mod(xo[2], TWO_PI);
            memcpy(X + slot * N, xo, N * sizeof(double));
            memcpy(P + slot * N * N, newP + c * N * N, N * N * sizeof(double));
        }
    }
    PyMem_Free(newX);
    PyMem_Free(newP);
    ret = ok ? Py_True : Py_False;
    Py_INCREF(ret);
r_m:
    PyBuffer_Release(&bM);
r_d:
    PyBuffer_Release(&bd);
r_a:
    PyBuffer_Release(&bA);
r_p:
    PyBuffer_Release(&bP);
r_x:
    PyBuffer_Release(&bX);
    return ret;
}

/* late_update(P, H, R, y, dx, M) -> NIS: a 1- or 2-D measurement update computed at a stored
 * step without applying it: dx = K y and the covariance reduction M = P - Joseph(P), for
 * correct(). NaN if the innovation covariance is not positive definite. */
static PyObject *k_late_update(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 6) {
        PyErr_SetString(PyExc_TypeError, "late_update(P, H, R, y, dx, M)");
        return NULL;
    }
    Py_buffer bP, bH, bR, by, bd, bM;
    PyObject *ret = NULL;
    double *P = get_doubles(args[0], &bP, N * N, "P");
    if (!P)
        return NULL;
    double *H = get_doubles(args[1], &bH, -N, "H");
    if (!H)
        goto u_p;
    int m = (int)(bH.len / (Py_ssize_t)(N * sizeof(double)));
    if (m > 2) {
        PyErr_SetString(PyExc_ValueError, "late_update: at most 2 rows");
        goto u_h;
    }
    double *R = get_doubles(args[2], &bR, m * m, "R");
    if (!R)
        goto u_h;
    double *y = get_doubles(args[3], &by, m, "y");
    if (!y)
        goto u_r;
    double *dx = get_doubles(args[4], &bd, N, "dx");
    if (!dx)
        goto u_y;
    double *Mo = get_doubles(args[5], &bM, N * N, "M");
    if (!Mo)
        goto u_d;
    double PHt[N][2], S[2][2], Si[2][2], K[N][2], nis;
    for (int a = 0; a < N; a++)
        for (int i = 0; i < m; i++) {
            double v = 0.0;
            for (int b = 0; b < N; b++)
                v += P[a * N + b] * H[i * N + b];
            PHt[a][i] = v;
        }
    for (int i = 0; i < m; i++)
        for (int j = 0; j < m; j++) {
            double v = 0.0;
            for (int a = 0; a < N; a++)
                v += H[i * N + a] * PHt[a][j];
            S[i][j] = v;
        }
    if (m == 2)
        S[0][1] = S[1][0] = 0.5 * (S[0][1] + S[1][0]);
    for (int i = 0; i < m; i++)
        for (int j = 0; j < m; j++)
            S[i][j] += R[i * m + j];
    if (m == 1) {
        if (!(S[0][0] > 0.0))
            goto not_pd;
        Si[0][0] = 1.0 / S[0][0];
        nis = y[0] * y[0] * Si[0][0];
    } else {
        double det = S[0][0] * S[1][1] - S[0][1] * S[1][0];
        if (!(S[0][0] > 0.0) || !(det > 0.0))
            goto not_pd;
        Si[0][0] = S[1][1] / det;
        Si[1][1] = S[0][0] / det;
        Si[0][1] = Si[1][0] = -S[0][1] / det;
        nis = y[0] * (Si[0][0] * y[0] + Si[0][1] * y[1]) + y[1] * (Si[1][0] * y[0] + Si[1][1] * y[1]);
    }
    for (int a = 0; a < N; a++) {
        double d = 0.0;
        for (int j = 0; j < m; j++) {
            double v = 0.0;
            for (int i = 0; i < m; i++)
                v += PHt[a][i] * Si[i][j];
            K[a][j] = v;
            d += v * y[j];
        }
        dx[a] = d;
    }
    {
        /* Joseph: B = P - K (H P) = P - K PHt'; J = B - (B H') K' + K R K'; M = P - J */
        double B[N * N], BHt[N][2];
        for (int a = 0; a < N; a++)
            for (int b = 0; b < N; b++) {
                double v = P[a * N + b];
                for (int i = 0; i < m; i++)
                    v -= K[a][i] * PHt[b][i];
                B[a * N + b] = v;
            }
        for (int a = 0; a < N; a++)
            for (int i = 0; i < m; i++) {
                double v = 0.0;
                for (int b = 0; b < N; b++)
                    v += B[a * N + b] * H[i * N + b];
                BHt[a][i] = v;
            }
        for (int a = 0; a < N; a++)
            for (int b = 0; b < N; b++) {
                double v = B[a * N + b];
                for (int i = 0; i < m; i++) {
                    v -= BHt[a][i] * K[b][i];
                    double kr = 0.0;
                    for (int j = 0; j < m; j++)
                        kr += K[a][j] * R[j * m + i];
                    v += kr * K[b][i];
                }
                Mo[a * N + b] = P[a * N + b] - v;
            }
        symmetrize(Mo);
    }
    ret = PyFloat_FromDouble(nis);
    goto u_m;
not_pd:
    ret = PyFloat_FromDouble(NAN);
u_m:
    PyBuffer_Release(&bM);
u_d:
    PyBuffer_Release(&bd);
u_y:
    PyBuffer_Release(&by);
u_r:
    PyBuffer_Release(&bR);
u_h:
    PyBuffer_Release(&bH);
u_p:
    PyBuffer_Release(&bP);
    return ret;
}

static PyObject *k_positive_definite(PyObject *self, PyObject *arg)
{
    Py_buffer b;
    double *P = get_doubles(arg, &b, -N * N, "P");
    if (!P)
        return NULL;
    Py_ssize_t n = b.len / (Py_ssize_t)(N * N * sizeof(double));
    int ok = 1;
    for (Py_ssize_t i = 0; i < n && ok; i++)
        ok = positive_definite(P + i * N * N);
    PyBuffer_Release(&b);
    return PyBool_FromLong(ok);
}

/* ---- the per-drive stiffness regression (fusion/stiffness_regression.py) ----------------------
 * One axle's 6-state filter [k1, k3, d_psi, e_b, tau, d0] and the windowed statistics of the ring
 * buffer it reads at each fused GNSS sample: the same math as the *_reference functions there,
 * without numpy's per-call overhead (it was most of a GNSS step). */
#define NS 6
#define S_DPSI 2
#define S_EB 3
#define S_TAU 4

/* axle_propagate(P, c, q_psi, q_bias): P <- F P F' (F = I + c e_dpsi e_eb'), then the heading and
 * bias random walks. */
static PyObject *k_axle_propagate(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4) {
        PyErr_SetString(PyExc_TypeError, "axle_propagate(P, c, q_psi, q_bias)");
        return NULL;
    }
    double c = PyFloat_AsDouble(args[1]), q_psi = PyFloat_AsDouble(args[2]), q_bias = PyFloat_AsDouble(args[3]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bp;
    double *P = get_doubles(args[0], &bp, NS * NS, "P");
    if (!P)
        return NULL;
    /* row d_psi += c row e_b, then column d_psi += c column e_b (F P, then (F P) F') */
    for (int b = 0; b < NS; b++)
        P[S_DPSI * NS + b] += c * P[S_EB * NS + b];
    for (int a = 0; a < NS; a++)
        P[a * NS + S_DPSI] += c * P[a * NS + S_EB];
    P[S_DPSI * NS + S_DPSI] += q_psi;
    P[S_EB * NS + S_EB] += q_bias;
    PyBuffer_Release(&bp);
    Py_RETURN_NONE;
}

/* axle_update(x, P, z, h, rv) -> normalised innovation: scalar Joseph-form update with the latency
 * state considered (its gain zero), P made exactly symmetric. */
static PyObject *k_axle_update(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "axle_update(x, P, z, h, rv)");
        return NULL;
    }
    double z = PyFloat_AsDouble(args[2]), rv = PyFloat_AsDouble(args[4]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bx, bp, bh;
    PyObject *ret = NULL;
    double *x = get_doubles(args[0], &bx, NS, "x");
    if (!x)
        return NULL;
    double *P = get_doubles(args[1], &bp, NS * NS, "P");
    if (!P)
        goto u_x;
    double *h = get_doubles(args[3], &bh, NS, "h");
    if (!h)
        goto u_p;
    double Ph[NS], g[NS], IKH[NS * NS], T[NS * NS];
    double s = 0.0, hx = 0.0;
    for (int a = 0; a < NS; a++) {
        double v = 0.0;
        for (int b = 0; b < NS; b++)
            v += P[a * NS + b] * h[b];
        Ph[a] = v;
    }
    for (int a = 0; a < NS; a++)
        s += h[a] * Ph[a];
    s += rv;
    for (int a = 0; a < NS; a++)
        hx += h[a] * x[a];
    double e = z - hx;
    for (int a = 0; a < NS; a++)
        g[a] = Ph[a] / s;
    g[S_TAU] = 0.0;
    for (int a = 0; a < NS; a++)
        x[a] += g[a] * e;
    for (int a = 0; a < NS; a++)
        for (int b = 0; b < NS; b++)
            IKH[a * NS + b] = (a == b ? 1.0 : 0.0) - g[a] * h[b];
    for (int a = 0; a < NS; a++) /* T = IKH P */
        for (int b = 0; b < NS; b++) {
            double v = 0.0;
            for (int k = 0; k < NS; k++)
                v += IKH[a * NS + k] * P[k * NS + b];
            T[a * NS + b] = v;
        }
    for (int a = 0; a < NS; a++) /* P = T IKH' + rv g g' */
        for (int b = 0; b < NS; b++) {
            double v = 0.0;
            for (int k = 0; k < NS; k++)
                v += T[a * NS + k] * IKH[b * NS + k];
            P[a * NS + b] = v + rv * (g[a] * g[b]);
        }
    for (int a = 0; a < NS; a++)
        for (int b = 0; b < a; b++) {
            double v = 0.5 * (P[a * NS + b] + P[b * NS + a]);
            P[a * NS + b] = v;
            P[b * NS + a] = v;
        }
    ret = PyFloat_FromDouble(e / sqrt(s));
    PyBuffer_Release(&bh);
u_p:
    PyBuffer_Release(&bp);
u_x:
    PyBuffer_Release(&bx);
    return ret;
}

/* axle_latency(x, P, tau, var): the considered latency moved to tau with variance var; the states
 * follow through their cross-covariance (Schmidt), P made exactly symmetric. */
static PyObject *k_axle_latency(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4) {
        PyErr_SetString(PyExc_TypeError, "axle_latency(x, P, tau, var)");
        return NULL;
    }
    double tau = PyFloat_AsDouble(args[2]), var = PyFloat_AsDouble(args[3]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bx, bp;
    double *x = get_doubles(args[0], &bx, NS, "x");
    if (!x)
        return NULL;
    double *P = get_doubles(args[1], &bp, NS * NS, "P");
    if (!P) {
        PyBuffer_Release(&bx);
        return NULL;
    }
    double p[NS];
    for (int a = 0; a < NS; a++)
        p[a] = P[a * NS + S_TAU];
    double pt = p[S_TAU], d = tau - x[S_TAU], c = 1.0 - var / pt;
    for (int a = 0; a < NS; a++)
        x[a] += p[a] / pt * d;
    for (int a = 0; a < NS; a++)
        for (int b = 0; b < NS; b++)
            P[a * NS + b] -= c * (p[a] * p[b]) / pt;
    for (int a = 0; a < NS; a++)
        for (int b = 0; b < a; b++) {
            double v = 0.5 * (P[a * NS + b] + P[b * NS + a]);
            P[a * NS + b] = v;
            P[b * NS + a] = v;
        }
    PyBuffer_Release(&bp);
    PyBuffer_Release(&bx);
    Py_RETURN_NONE;
}

/* Row k of a ring buffer of n rows (Python's k % n). */
static Py_ssize_t ring_row(long long k, Py_ssize_t n)
{
    long long r = k % n;
    return (Py_ssize_t)(r < 0 ? r + n : r);
}

/* gyro_sum(aux, r_col, X, br_col, k0, k1) -> sum over steps k0..k1 of aux[k, r_col] + X[k, br_col]
 * (ring buffers of the same number of rows): the gyro's own reading, bias added back. */
static PyObject *k_gyro_sum(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 6) {
        PyErr_SetString(PyExc_TypeError, "gyro_sum(aux, r_col, X, br_col, k0, k1)");
        return NULL;
    }
    long r_col = PyLong_AsLong(args[1]), br_col = PyLong_AsLong(args[3]);
    long long k0 = PyLong_AsLongLong(args[4]), k1 = PyLong_AsLongLong(args[5]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer ba, bX;
    double *aux = get_doubles(args[0], &ba, -1, "aux");
    if (!aux)
        return NULL;
    double *X = get_doubles(args[2], &bX, -1, "X");
    if (!X) {
        PyBuffer_Release(&ba);
        return NULL;
    }
    PyObject *ret = NULL;
    Py_ssize_t na = ba.len / (Py_ssize_t)sizeof(double), nx = bX.len / (Py_ssize_t)sizeof(double);
    Py_ssize_t rows = ba.ndim == 2 ? ba.shape[0] : -1;
    if (rows <= 0 || bX.ndim != 2 || bX.shape[0] != rows || r_col < 0 || r_col >= na / rows || br_col < 0
        || br_col >= nx / rows) {
        PyErr_SetString(PyExc_ValueError, "gyro_sum: aux and X must have the same rows, columns in range");
        goto g_done;
    }
    Py_ssize_t ca = na / rows, cx = nx / rows;
    double sum = 0.0;
    for (long long k = k0; k <= k1; k++) {
        Py_ssize_t i = ring_row(k, rows);
        sum += aux[i * ca + r_col] + X[i * cx + br_col];
    }
    ret = PyFloat_FromDouble(sum);
g_done:
    PyBuffer_Release(&bX);
    PyBuffer_Release(&ba);
    return ret;
}

/* numpy's np.sum of a contiguous float64 array, bit for bit: its pairwise summation (numpy's
 * loops_utils.h: below 8 values one chain from -0.0; up to 128 eight chains, combined
 * ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7)), the rest added in order; above, split in two at a
 * multiple of 8), added to the reduction's initial +0.0. tests/test_kernels.py compares it with
 * np.sum itself on random arrays of every length it meets. */
static double pairwise_sum(const double *a, Py_ssize_t n)
{
    if (n < 8) {
        double res = -0.0;
        for (Py_ssize_t i = 0; i < n; i++)
            res += a[i];
        return res;
    }
    if (n <= 128) {
        double r[8];
        memcpy(r, a, sizeof(r));
        Py_ssize_t i;
        for (i = 8; i < n - (n % 8); i += 8)
            for (int j = 0; j < 8; j++)
                r[j] += a[i + j];
        double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++)
            res += a[i];
        return res;
    }
    Py_ssize_t n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise_sum(a, n2) + pairwise_sum(a + n2, n - n2);
}

/* yaw_sum(aux, r_col, k0, k1, ring) -> lever_arm_check.yaw_sum_reference, numpy's bits: the sum
 * over steps k0..k1 of aux[k, r_col] (ring None) or aux[k, r_col] / (1 - ring[k]) (ring buffers
 * of the same rows), as np.sum of the gathered (and divided) column. Why: the lever-arm and
 * gyro-scale checks' gyro turn between fixes was ~8 numpy calls per fix. */
static PyObject *k_yaw_sum(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "yaw_sum(aux, r_col, k0, k1, ring)");
        return NULL;
    }
    long r_col = PyLong_AsLong(args[1]);
    long long k0 = PyLong_AsLongLong(args[2]), k1 = PyLong_AsLongLong(args[3]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer ba, bq;
    int has_ring = args[4] != Py_None;
    double *aux = get_doubles(args[0], &ba, -1, "aux");
    if (!aux)
        return NULL;
    double *ring = NULL, *buf = NULL;
    PyObject *ret = NULL;
    Py_ssize_t na = ba.len / (Py_ssize_t)sizeof(double), rows = ba.ndim == 2 ? ba.shape[0] : -1;
    if (has_ring && !(ring = get_doubles(args[4], &bq, rows > 0 ? rows : 1, "ring"))) {
        PyBuffer_Release(&ba);
        return NULL;
    }
    long long count = k1 - k0 + 1;
    if (rows <= 0 || r_col < 0 || r_col >= na / rows || count > rows) {
        PyErr_SetString(PyExc_ValueError, "yaw_sum: column out of range or a window longer than the ring");
        goto y_done;
    }
    if (count < 0)
        count = 0;
    buf = PyMem_Malloc((size_t)(count > 0 ? count : 1) * sizeof(double));
    if (!buf) {
        PyErr_NoMemory();
        goto y_done;
    }
    Py_ssize_t ca = na / rows;
    for (long long c = 0; c < count; c++) {
        Py_ssize_t i = ring_row(k0 + c, rows);
        buf[c] = has_ring ? aux[i * ca + r_col] / (1.0 - ring[i]) : aux[i * ca + r_col];
    }
    ret = PyFloat_FromDouble(0.0 + pairwise_sum(buf, (Py_ssize_t)count));
    PyMem_Free(buf);
y_done:
    if (has_ring)
        PyBuffer_Release(&bq);
    PyBuffer_Release(&ba);
    return ret;
}

/* window_fit(aux, r_col, ay_col, lo, hi, s, dt) -> (r_dot, r, ay, std of the ay mean): over steps
 * lo..hi of the ring buffer, the least-squares line r = r + r_dot t (t = (k - s) dt) and the mean
 * of ay with the standard error of that mean. */
static PyObject *k_window_fit(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "window_fit(aux, r_col, ay_col, lo, hi, s, dt)");
        return NULL;
    }
    long r_col = PyLong_AsLong(args[1]), ay_col = PyLong_AsLong(args[2]);
    long long lo = PyLong_AsLongLong(args[3]), hi = PyLong_AsLongLong(args[4]), s = PyLong_AsLongLong(args[5]);
    double dt = PyFloat_AsDouble(args[6]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer ba;
    double *aux = get_doubles(args[0], &ba, -1, "aux");
    if (!aux)
        return NULL;
    PyObject *ret = NULL;
    Py_ssize_t na = ba.len / (Py_ssize_t)sizeof(double), rows = ba.ndim == 2 ? ba.shape[0] : -1;
    long long m = hi - lo + 1;
    if (rows <= 0 || r_col < 0 || r_col >= na / rows || ay_col < 0 || ay_col >= na / rows || m < 2 || m > rows) {
        PyErr_SetString(PyExc_ValueError, "window_fit: columns or window out of range");
        goto w_done;
    }
    Py_ssize_t ca = na / rows;
    double st = 0.0, sr = 0.0, say = 0.0;
    for (long long k = lo; k <= hi; k++) {
        Py_ssize_t i = ring_row(k, rows);
        st += (double)(k - s) * dt;
        sr += aux[i * ca + r_col];
        say += aux[i * ca + ay_col];
    }
    double tm = st / (double)m, rm = sr / (double)m, aym = say / (double)m;
    double stt = 0.0, str = 0.0, sdd = 0.0;
    for (long long k = lo; k <= hi; k++) {
        Py_ssize_t i = ring_row(k, rows);
        double dtk = (double)(k - s) * dt - tm, da = aux[i * ca + ay_col] - aym;
        stt += dtk * dtk;
        str += dtk * (aux[i * ca + r_col] - rm);
        sdd += da * da;
    }
    double slope = str / stt;
    ret = Py_BuildValue("(dddd)", slope, rm - slope * tm, aym, sqrt(sdd / (double)m) / sqrt((double)m));
w_done:
    PyBuffer_Release(&ba);
    return ret;
}

/* ---- the single-track model's live cornering-compliance learner (fusion/single_track.py) ---- */

/* rls_update(k, P, P0, phi, n2, y, rv, lam) -> e: one RLS step of AxleRls's [k1, k3] in place,
 * regressor h = [phi, phi n2]; e = y - h'k before the step. P is kept from growing beyond the
 * prior P0 under forgetting: min(P, P0) entrywise if P is still positive definite, else P0 (the
 * 2x2 eigenvalues of its lower triangle, as numpy's eigvalsh takes them). */
static PyObject *k_rls_update(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 8) {
        PyErr_SetString(PyExc_TypeError, "rls_update(k, P, P0, phi, n2, y, rv, lam)");
        return NULL;
    }
    double phi = PyFloat_AsDouble(args[3]), n2 = PyFloat_AsDouble(args[4]);
    double y = PyFloat_AsDouble(args[5]), rv = PyFloat_AsDouble(args[6]), lam = PyFloat_AsDouble(args[7]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bk, bp, b0;
    double *k = get_doubles(args[0], &bk, 2, "k");
    if (!k)
        return NULL;
    double *P = get_doubles(args[1], &bp, 4, "P");
    if (!P) {
        PyBuffer_Release(&bk);
        return NULL;
    }
    double *P0 = get_doubles(args[2], &b0, 4, "P0");
    if (!P0) {
        PyBuffer_Release(&bp);
        PyBuffer_Release(&bk);
        return NULL;
    }
    double h[2] = {phi, phi * n2};
    double Ph[2] = {P[0] * h[0] + P[1] * h[1], P[2] * h[0] + P[3] * h[1]};
    double S = (h[0] * Ph[0] + h[1] * Ph[1]) + rv;
    double g[2] = {Ph[0] / S, Ph[1] / S};
    double e = y - (h[0] * k[0] + h[1] * k[1]);
    k[0] += g[0] * e;
    k[1] += g[1] * e;
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++)
            P[a * 2 + b] = (P[a * 2 + b] - g[a] * Ph[b]) / lam;
    if (P[0] > P0[0] || P[3] > P0[3]) {
        double m = 0.5 * (P[0] + P[3]), r = hypot(0.5 * (P[0] - P[3]), P[2]);
        int pd = m - r > 0.0; /* the smaller eigenvalue (lower triangle); NaN: not */
        for (int a = 0; a < 4; a++)
            P[a] = pd && !(P0[a] < P[a]) ? P[a] : P0[a]; /* numpy's minimum keeps a NaN */
    }
    PyBuffer_Release(&b0);
    PyBuffer_Release(&bp);
    PyBuffer_Release(&bk);
    return PyFloat_FromDouble(e);
}

/* The (A, S_prev, S_out) arguments of a sensitivity's per-step carry (sens_step, scale_step): an
 * 8 x 8 transition and two 8-vectors; on failure nothing is held and the exception is set. */
static int get_step_buffers(PyObject *const *args, Py_buffer *bA, Py_buffer *bp, Py_buffer *bo,
                            double **A, double **sp, double **so)
{
    if (!(*A = get_doubles(args[0], bA, N * N, "A")))
        return 0;
    if (!(*sp = get_doubles(args[1], bp, N, "S_prev"))) {
        PyBuffer_Release(bA);
        return 0;
    }
    if (!(*so = get_doubles(args[2], bo, N, "S_out"))) {
        PyBuffer_Release(bp);
        PyBuffer_Release(bA);
        return 0;
    }
    return 1;
}

/* ---- the latency sensitivity S of latency_sensitivity.py (one 8-vector per history slot) ---------
 * Carried through every step's effective transition and, at each fused GNSS fix, updated at the
 * fix's stored step and carried to the present: numpy's per-call overhead and the prefix-product
 * copies were most of that (~100 us per fix); here it is one 8 x 8 matrix-vector product per step
 * of delay. The sums run in index order (not BLAS's): the same math as the references, not their
 * last bits (tests/test_kernels.py: within 1e-12). */

/* sens_step(A, S_prev, S_out): S_out = A S_prev (one step's transition). */
static PyObject *k_sens_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "sens_step(A, S_prev, S_out)");
        return NULL;
    }
    Py_buffer bA, bp, bo;
    double *A, *sp, *so;
    if (!get_step_buffers(args, &bA, &bp, &bo, &A, &sp, &so))
        return NULL;
    double v[N];
    for (int a = 0; a < N; a++) {
        double t = 0.0;
        for (int b = 0; b < N; b++)
            t += A[a * N + b] * sp[b];
        v[a] = t;
    }
    memcpy(so, v, sizeof(v)); /* S_out may be S_prev */
    PyBuffer_Release(&bo);
    PyBuffer_Release(&bp);
    PyBuffer_Release(&bA);
    Py_RETURN_NONE;
}

/* numpy's BLAS, reproduced: 8x8 products with the bits numpy's matmul / dot give them where its
 * OpenBLAS runs the Haswell kernels (x86-64): a matrix product's every element one fused
 * multiply-add chain over k in index order from +0 (dgemm); a matrix-vector product's every
 * element four such chains over k = m, m + 4 (lanes m = 0..3), summed (l0 + l2) + (l1 + l3)
 * (dgemv). Why: the scale sensitivity's carry of a 0.5 s rewind (scale_sensitivity.py) is ~450
 * products by doubling and ~80 matrix-vector ones, each a whole BLAS call through numpy's gufunc
 * machinery (~2 k instructions for 1 k flops): it was ~40 % of a fused GNSS fix. backend.select
 * compares these with numpy's own on probe products and keeps the numpy references where they
 * differ (another BLAS or CPU): the estimate's bits never depend on which of the two ran. */
#if defined(__GNUC__) && defined(__x86_64__)
#define BLAS_FMA_TARGET 1
#include <immintrin.h>
__attribute__((target("avx2,fma"))) static void mm8_fma(const double *x, const double *y, double *out)
{
    __m256d yk[2 * N]; /* y's rows, loaded once */
    for (int k = 0; k < N; k++) {
        yk[2 * k] = _mm256_loadu_pd(y + k * N);
        yk[2 * k + 1] = _mm256_loadu_pd(y + k * N + 4);
    }
    for (int i = 0; i < N; i++) { /* row i: each element's chain in k order, four elements a lane */
        __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd();
        for (int k = 0; k < N; k++) {
            __m256d b = _mm256_broadcast_sd(x + i * N + k);
            a0 = _mm256_fmadd_pd(b, yk[2 * k], a0);
            a1 = _mm256_fmadd_pd(b, yk[2 * k + 1], a1);
        }
        _mm256_storeu_pd(out + i * N, a0);
        _mm256_storeu_pd(out + i * N + 4, a1);
    }
}

__attribute__((target("avx2,fma"))) static void mv8_fma(const double *a, const double *x, double *y)
{
    for (int i = 0; i < N; i++) {
        double l[4] = {0.0, 0.0, 0.0, 0.0};
        for (int k = 0; k < N; k++)
            l[k % 4] = __builtin_fma(a[i * N + k], x[k], l[k % 4]);
        y[i] = (l[0] + l[2]) + (l[1] + l[3]);
    }
}
#endif

static void mm8_libm(const double *x, const double *y, double *out)
{
    for (int i = 0; i < N; i++) {
        double acc[N] = {0.0};
        for (int k = 0; k < N; k++)
            for (int j = 0; j < N; j++)
                acc[j] = fma(x[i * N + k], y[k * N + j], acc[j]); /* correctly rounded, as the instruction */
        memcpy(out + i * N, acc, sizeof(acc));
    }
}

static void mv8_libm(const double *a, const double *x, double *y)
{
    for (int i = 0; i < N; i++) {
        double l[4] = {0.0, 0.0, 0.0, 0.0};
        for (int k = 0; k < N; k++)
            l[k % 4] = fma(a[i * N + k], x[k], l[k % 4]);
        y[i] = (l[0] + l[2]) + (l[1] + l[3]);
    }
}

typedef void (*mm8_fn)(const double *, const double *, double *);

static void blas8(mm8_fn *mm, mm8_fn *mv)
{
    *mm = mm8_libm;
    *mv = mv8_libm;
#ifdef BLAS_FMA_TARGET
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
        *mm = mm8_fma;
        *mv = mv8_fma;
    }
#endif
}

/* phis[j] <- phis[j] ... phis[0] in place: for d = 1, 2, 4, ...: phis[d:] = phis[d:] @ phis[:-d]. */
static void doubling(double *phis, Py_ssize_t count, mm8_fn mm)
{
    double t[N * N];
    for (Py_ssize_t d = 1; d < count; d *= 2)
        for (Py_ssize_t j = count - 1; j >= d; j--) { /* descending: phis[j - d] is still the old one */
            mm(phis + j * N * N, phis + (j - d) * N * N, t);
            memcpy(phis + j * N * N, t, sizeof(t));
        }
}

/* prefix_doubling(phis): latency_sensitivity.prefix_doubling_reference, numpy's bits (above). */
static PyObject *k_prefix_doubling(PyObject *self, PyObject *arg)
{
    Py_buffer b;
    double *phis = get_doubles(arg, &b, -(N * N), "phis");
    if (!phis)
        return NULL;
    mm8_fn mm, mv;
    blas8(&mm, &mv);
    doubling(phis, b.len / (Py_ssize_t)(N * N * sizeof(double)), mm);
    PyBuffer_Release(&b);
    Py_RETURN_NONE;
}

/* carry_change(S, A, s, last, delta): scale_sensitivity.carry_change_reference, numpy's bits:
 * S at every slot of steps s+1 .. last += (A_j ... A_{s+1}) delta (ring of len(S) slots). */
static PyObject *k_carry_change(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "carry_change(S, A, s, last, delta)");
        return NULL;
    }
    long long s = PyLong_AsLongLong(args[2]), last = PyLong_AsLongLong(args[3]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bS, bA, bd;
    double *S = get_doubles(args[0], &bS, -N, "S");
    if (!S)
        return NULL;
    double *A = get_doubles(args[1], &bA, -(N * N), "A");
    if (!A) {
        PyBuffer_Release(&bS);
        return NULL;
    }
    double *delta = get_doubles(args[4], &bd, N, "delta");
    if (!delta) {
        PyBuffer_Release(&bA);
        PyBuffer_Release(&bS);
        return NULL;
    }
    Py_ssize_t n = bS.len / (Py_ssize_t)(N * sizeof(double));
    PyObject *ret = NULL;
    long long count = last - s;
    if (bA.len / (Py_ssize_t)(N * N * sizeof(double)) != n || count >= n) {
        PyErr_SetString(PyExc_ValueError, "carry_change: A and S must hold the same slots, the window fewer");
        goto done;
    }
    if (count > 0) {
        double *phis = PyMem_Malloc((size_t)count * N * N * sizeof(double));
        if (!phis) {
            PyErr_NoMemory();
            goto done;
        }
        for (long long c = 0; c < count; c++) {
            long long k = s + 1 + c, slot = ((k % n) + n) % n;
            memcpy(phis + c * N * N, A + slot * N * N, N * N * sizeof(double));
        }
        mm8_fn mm, mv;
        blas8(&mm, &mv);
        doubling(phis, (Py_ssize_t)count, mm);
        for (long long c = 0; c < count; c++) {
            long long k = s + 1 + c, slot = ((k % n) + n) % n;
            double v[N];
            mv(phis + c * N * N, delta, v);
            for (int a = 0; a < N; a++)
                S[slot * N + a] = S[slot * N + a] + v[a];
        }
        PyMem_Free(phis);
    }
    ret = Py_None;
    Py_INCREF(ret);
done:
    PyBuffer_Release(&bd);
    PyBuffer_Release(&bA);
    PyBuffer_Release(&bS);
    return ret;
}

/* scale_step(A, S_prev, S_out, i, r_dt): scale_sensitivity.scale_step_reference, numpy's bits:
 * S_out = A S_prev, then S_out[i] += r_dt (i: the heading's index). */
static PyObject *k_scale_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "scale_step(A, S_prev, S_out, i, r_dt)");
        return NULL;
    }
    long ipsi = PyLong_AsLong(args[3]);
    double r_dt = PyFloat_AsDouble(args[4]);
    if (PyErr_Occurred())
        return NULL;
    if (ipsi < 0 || ipsi >= N) {
        PyErr_SetString(PyExc_ValueError, "scale_step: index outside the state");
        return NULL;
    }
    Py_buffer bA, bp, bo;
    double *A, *sp, *so;
    if (!get_step_buffers(args, &bA, &bp, &bo, &A, &sp, &so))
        return NULL;
    mm8_fn mm, mv;
    blas8(&mm, &mv);
    double v[N];
    mv(A, sp, v);
    memcpy(so, v, sizeof(v)); /* S_out may be S_prev */
    so[ipsi] = so[ipsi] + r_dt;
    PyBuffer_Release(&bo);
    PyBuffer_Release(&bp);
    PyBuffer_Release(&bA);
    Py_RETURN_NONE;
}

/* across_secant(aux, c, sn, u0, u1, lever_x, lever_y, dt, i0, span, slope):
 * latency_sensitivity.across_secant_reference, bit for bit (elementwise IEEE operations in numpy's
 * order, the cumulative sum left to right as numpy's accumulate, argmax's first maximum, a NaN
 * first): the antenna's acceleration across the track over the stored rows aux (count x 6, the
 * history's aux columns; c, sn the cos / sin of their headings, from numpy), integrated, and its
 * largest timing secant about row i0. Why: ~25 numpy calls on ~100-element arrays per fused fix. */
static PyObject *k_across_secant(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 11) {
        PyErr_SetString(PyExc_TypeError, "across_secant(aux, c, sn, u0, u1, lever_x, lever_y, dt, i0, span, slope)");
        return NULL;
    }
    double sc[6];
    const int at[6] = {3, 4, 5, 6, 7, 9}; /* u0, u1, lever_x, lever_y, dt, span */
    for (int a = 0; a < 6; a++) {
        sc[a] = PyFloat_AsDouble(args[at[a]]);
        if (sc[a] == -1.0 && PyErr_Occurred())
            return NULL;
    }
    double u0 = sc[0], u1 = sc[1], lx = sc[2], ly = sc[3], dt = sc[4], span = sc[5];
    double slope = PyFloat_AsDouble(args[10]);
    if (slope == -1.0 && PyErr_Occurred())
        return NULL;
    Py_ssize_t i0 = PyLong_AsSsize_t(args[8]);
    if (i0 == -1 && PyErr_Occurred())
        return NULL;
    Py_buffer ba, bc, bs;
    double *aux = get_doubles(args[0], &ba, -6, "aux");
    if (!aux)
        return NULL;
    Py_ssize_t count = ba.len / (Py_ssize_t)(6 * sizeof(double));
    double *c = get_doubles(args[1], &bc, count, "c");
    if (!c) {
        PyBuffer_Release(&ba);
        return NULL;
    }
    double *sn = get_doubles(args[2], &bs, count, "sn");
    if (!sn) {
        PyBuffer_Release(&bc);
        PyBuffer_Release(&ba);
        return NULL;
    }
    PyObject *ret = NULL;
    double *y = NULL;
    if (i0 < 0 || i0 >= count) {
        PyErr_SetString(PyExc_IndexError, "across_secant: i0 outside the rows");
        goto done;
    }
    y = PyMem_Malloc((size_t)count * sizeof(double));
    if (!y) {
        PyErr_NoMemory();
        goto done;
    }
    double cum = 0.0;
    for (Py_ssize_t j = 0; j < count; j++) {
        const double *a = aux + j * 6;
        double rr = a[0], rd = a[2]; /* AUX_R, AUX_RDOT */
        double bx = (a[5] - rd * ly) - (rr * rr) * lx; /* AUX_AX */
        double by = (a[1] + rd * lx) - (rr * rr) * ly; /* AUX_AY */
        double across = u1 * (bx * c[j] + by * sn[j]) - u0 * (bx * sn[j] - by * c[j]);
        cum = j ? cum + across : across;
        y[j] = cum;
    }
    for (Py_ssize_t j = 0; j < count; j++)
        y[j] = y[j] * dt;
    double y0 = y[i0], best = 0.0;
    Py_ssize_t jb = -1;
    for (Py_ssize_t j = 0; j < count; j++) {
        double lag = (double)(j - i0) * dt;
        double al = fabs(lag);
        double m = (isnan(al) || isnan(span)) ? NAN : (al <= span ? al : span);
        double sg = lag > 0.0 ? 1.0 : (lag < 0.0 ? -1.0 : (isnan(lag) ? lag : 0.0));
        double cap = j == i0 ? 1.0 : sg * m;
        double sec = (y[j] - y0) / cap;
        double as = fabs(sec);
        if (isnan(as)) { /* numpy's argmax: the first NaN */
            jb = j;
            best = sec;
            break;
        }
        if (jb < 0 || as > fabs(best)) {
            jb = j;
            best = sec;
        }
    }
    ret = PyFloat_FromDouble(fabs(best) > fabs(slope) ? best : slope);
done:
    PyMem_Free(y);
    PyBuffer_Release(&bs);
    PyBuffer_Release(&bc);
    PyBuffer_Release(&ba);
    return ret;
}

/* K = P H' (H P H' + R)^-1 for m = 1 or 2 rows (sums in index order, the 2 x 2 inverse by its
 * adjugate); -1 (a ValueError set, naming `who`) if H P H' + R is singular. */
static int fused_gain(const double *P, const double *H, const double *R, int m, double *K, const char *who)
{
    double PHt[N * 2], Sm[4], Si[4];
    for (int a = 0; a < N; a++) /* P H' */
        for (int r = 0; r < m; r++) {
            double v = 0.0;
            for (int b = 0; b < N; b++)
                v += P[a * N + b] * H[r * N + b];
            PHt[a * m + r] = v;
        }
    for (int r = 0; r < m; r++) /* H P H' + R */
        for (int q = 0; q < m; q++) {
            double v = 0.0;
            for (int a = 0; a < N; a++)
                v += H[r * N + a] * PHt[a * m + q];
            Sm[r * m + q] = v + R[r * m + q];
        }
    if (m == 1) {
        if (Sm[0] == 0.0) {
            PyErr_Format(PyExc_ValueError, "%s: singular innovation covariance", who);
            return -1;
        }
        Si[0] = 1.0 / Sm[0];
    } else {
        double det = Sm[0] * Sm[3] - Sm[1] * Sm[2];
        if (det == 0.0) {
            PyErr_Format(PyExc_ValueError, "%s: singular innovation covariance", who);
            return -1;
        }
        Si[0] = Sm[3] / det;
        Si[1] = -Sm[1] / det;
        Si[2] = -Sm[2] / det;
        Si[3] = Sm[0] / det;
    }
    for (int a = 0; a < N; a++) /* K = P H' S^-1 */
        for (int q = 0; q < m; q++) {
            double v = 0.0;
            for (int r = 0; r < m; r++)
                v += PHt[a * m + r] * Si[r * m + q];
            K[a * m + q] = v;
        }
    return 0;
}

/* The operands sens_fused and scale_fused share: S (n slots of N), the n stored transitions A,
 * the covariance P before the fix, its m = 1 or 2 Jacobian rows H and noise R, and the stored step
 * s it is fused at, which the history must still hold up to last. 0 (every view released, the
 * error set) when one is missing or wrong. */
typedef struct {
    Py_buffer S, A, P, H, R;
    double *s, *a, *p, *h, *r;
    Py_ssize_t n;
    int m;
} FusedOperands;

static void release_fused(FusedOperands *o)
{
    PyBuffer_Release(&o->R);
    PyBuffer_Release(&o->H);
    PyBuffer_Release(&o->P);
    PyBuffer_Release(&o->A);
    PyBuffer_Release(&o->S);
}

static int get_fused_operands(PyObject *const *args, long long s, long long last, const char *who,
                              FusedOperands *o)
{
    if (!(o->s = get_doubles(args[0], &o->S, -N, "S")))
        return 0;
    o->n = o->S.len / (Py_ssize_t)(N * sizeof(double));
    if (!(o->a = get_doubles(args[1], &o->A, o->n * N * N, "A")))
        goto f_s;
    if (!(o->p = get_doubles(args[2], &o->P, N * N, "P")))
        goto f_a;
    if (!(o->h = get_doubles(args[3], &o->H, -N, "H")))
        goto f_p;
    o->m = (int)(o->H.len / (Py_ssize_t)(N * sizeof(double)));
    if (o->m > 2) {
        PyErr_Format(PyExc_ValueError, "%s: H must have 1 or 2 rows", who);
        goto f_h;
    }
    if (!(o->r = get_doubles(args[4], &o->R, o->m * o->m, "R")))
        goto f_h;
    if (last - s < 0 || last - s >= o->n) {
        PyErr_Format(PyExc_ValueError, "%s: step outside the history", who);
        PyBuffer_Release(&o->R);
        goto f_h;
    }
    return 1;
f_h:
    PyBuffer_Release(&o->H);
f_p:
    PyBuffer_Release(&o->P);
f_a:
    PyBuffer_Release(&o->A);
f_s:
    PyBuffer_Release(&o->S);
    return 0;
}

/* sens_fused(S, A, P, H, R, h, s, last): a fix of m = 1 or 2 rows fused at stored step s with
 * Jacobian H and noise R against the covariance P it had before: with K = P H' (H P H' + R)^-1,
 * S_s <- S_s - K (H S_s - h), then S_j = A_j S_{j-1} for every later step j up to last. */
static PyObject *k_sens_fused(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 8) {
        PyErr_SetString(PyExc_TypeError, "sens_fused(S, A, P, H, R, h, s, last)");
        return NULL;
    }
    long long s = PyLong_AsLongLong(args[6]), last = PyLong_AsLongLong(args[7]);
    if (PyErr_Occurred())
        return NULL;
    FusedOperands o;
    if (!get_fused_operands(args, s, last, "sens_fused", &o))
        return NULL;
    PyObject *ret = NULL;
    Py_buffer bh;
    const int m = o.m;
    const double *H = o.h, *A = o.a;
    double *S = o.s;
    double *hv = get_doubles(args[5], &bh, m, "h");
    if (!hv)
        goto done;
    double K[N * 2], innov[2];
    if (fused_gain(o.p, H, o.r, m, K, "sens_fused") < 0)
        goto f_hv;
    double *Ss = S + ring_row(s, o.n) * N;
    for (int r = 0; r < m; r++) { /* H S_s - h */
        double v = 0.0;
        for (int b = 0; b < N; b++)
            v += H[r * N + b] * Ss[b];
        innov[r] = v - hv[r];
    }
    for (int a = 0; a < N; a++) {
        double v = 0.0;
        for (int r = 0; r < m; r++)
            v += K[a * m + r] * innov[r];
        Ss[a] -= v;
    }
    const double *prev = Ss;
    for (long long j = s + 1; j <= last; j++) { /* S_j = A_j S_{j-1} */
        Py_ssize_t i = ring_row(j, o.n);
        const double *Aj = A + i * N * N;
        double *Sj = S + i * N;
        for (int a = 0; a < N; a++) {
            double v = 0.0;
            for (int b = 0; b < N; b++)
                v += Aj[a * N + b] * prev[b];
            Sj[a] = v;
        }
        prev = Sj;
    }
    ret = Py_None;
    Py_INCREF(ret);
f_hv:
    PyBuffer_Release(&bh);
done:
    release_fused(&o);
    return ret;
}

/* scale_fused(S, A, P, H, R, s, last): scale_sensitivity.scale_fused_reference, the same math: a
 * fix of m = 1 or 2 rows fused at stored step s (K as sens_fused's) changes S_s by
 * delta = -K H S_s, and every later step j up to last by A_j ... A_{s+1} delta, carried one step
 * at a time (d_j = A_j d_{j-1}: ~80 matrix-vector products where the reference's doubling takes
 * ~450 matrix ones to keep numpy's bits, the largest part of a fused fix). */
static PyObject *k_scale_fused(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "scale_fused(S, A, P, H, R, s, last)");
        return NULL;
    }
    long long s = PyLong_AsLongLong(args[5]), last = PyLong_AsLongLong(args[6]);
    if (PyErr_Occurred())
        return NULL;
    FusedOperands o;
    if (!get_fused_operands(args, s, last, "scale_fused", &o))
        return NULL;
    PyObject *ret = NULL;
    const int m = o.m;
    const double *H = o.h, *A = o.a;
    double *S = o.s;
    double K[N * 2], hs[2], d[N], v[N];
    if (fused_gain(o.p, H, o.r, m, K, "scale_fused") < 0)
        goto done;
    double *Ss = S + ring_row(s, o.n) * N;
    for (int r = 0; r < m; r++) { /* H S_s */
        double t = 0.0;
        for (int b = 0; b < N; b++)
            t += H[r * N + b] * Ss[b];
        hs[r] = t;
    }
    for (int a = 0; a < N; a++) { /* delta = -K (H S_s) */
        double t = 0.0;
        for (int r = 0; r < m; r++)
            t += K[a * m + r] * hs[r];
        d[a] = -t;
        Ss[a] = Ss[a] + d[a];
    }
    for (long long j = s + 1; j <= last; j++) { /* d_j = A_j d_{j-1}; S_j += d_j */
        Py_ssize_t i = ring_row(j, o.n);
        const double *Aj = A + i * N * N;
        double *Sj = S + i * N;
        for (int a = 0; a < N; a++) {
            double t = 0.0;
            for (int b = 0; b < N; b++)
                t += Aj[a * N + b] * d[b];
            v[a] = t;
        }
        for (int a = 0; a < N; a++) {
            d[a] = v[a];
            Sj[a] = Sj[a] + v[a];
        }
    }
    ret = Py_None;
    Py_INCREF(ret);
done:
    release_fused(&o);
    return ret;
}

/* ---- the lever-arm checks' fits (lever_arm_check.py): p <= 8 unknowns, information form -------
 * At every GNSS fix each receiver's two checks add the fix to their information and solve the
 * regularised fit again: a handful of numpy calls and a LAPACK inverse each (~100 us per fix, the
 * largest part of a fix's fusion). The information update is the reference's elementwise
 * arithmetic (the same bits); the inverse is Gauss-Jordan with partial pivoting and the products
 * are summed in index order (the same math as numpy's LAPACK/BLAS, not their last bits). */
#define FIT_MAX 8

/* fit_update(info, rhs, h, z, var, prior, theta, cov) -> solved: info += h h' / var,
 * rhs += h (z / var); then cov = (info + diag(prior))^-1, theta = cov rhs. False (theta and cov
 * untouched) while info + diag(prior) is singular (a zero pivot, as LAPACK's getrf). */
static PyObject *k_fit_update(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 8) {
        PyErr_SetString(PyExc_TypeError, "fit_update(info, rhs, h, z, var, prior, theta, cov)");
        return NULL;
    }
    double z = PyFloat_AsDouble(args[3]), var = PyFloat_AsDouble(args[4]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer b[6];
    double *v[6];
    int nb = 0;
    PyObject *ret = NULL;
    static const int which[6] = {2, 0, 1, 5, 6, 7}; /* h first: it gives p */
    static const char *names[6] = {"h", "info", "rhs", "prior", "theta", "cov"};
    int p = 0;
    for (; nb < 6; nb++) {
        Py_ssize_t want = nb == 0 ? -1 : (nb == 1 || nb == 5) ? (Py_ssize_t)p * p : p;
        v[nb] = get_doubles(args[which[nb]], &b[nb], want, names[nb]);
        if (!v[nb])
            goto done;
        if (nb == 0) {
            p = (int)(b[0].len / (Py_ssize_t)sizeof(double));
            if (p > FIT_MAX) {
                PyErr_SetString(PyExc_ValueError, "fit_update: at most 8 unknowns");
                nb++;
                goto done;
            }
        }
    }
    double *h = v[0], *info = v[1], *rhs = v[2], *prior = v[3], *theta = v[4], *cov = v[5];
    double zv = z / var;
    for (int i = 0; i < p; i++) {
        for (int j = 0; j < p; j++)
            info[i * p + j] += h[i] * h[j] / var;
        rhs[i] += h[i] * zv;
    }
    double a[FIT_MAX * FIT_MAX], inv[FIT_MAX * FIT_MAX];
    for (int i = 0; i < p; i++)
        for (int j = 0; j < p; j++) {
            a[i * p + j] = info[i * p + j] + (i == j ? prior[i] : 0.0);
            inv[i * p + j] = i == j ? 1.0 : 0.0;
        }
    int ok = 1;
    for (int c = 0; c < p && ok; c++) {
        int piv = c;
        for (int r = c + 1; r < p; r++)
            if (fabs(a[r * p + c]) > fabs(a[piv * p + c]))
                piv = r;
        if (a[piv * p + c] == 0.0) {
            ok = 0;
            break;
        }
        if (piv != c)
            for (int j = 0; j < p; j++) {
                double t = a[c * p + j];
                a[c * p + j] = a[piv * p + j];
                a[piv * p + j] = t;
                t = inv[c * p + j];
                inv[c * p + j] = inv[piv * p + j];
                inv[piv * p + j] = t;
            }
        double d = a[c * p + c];
        for (int j = 0; j < p; j++) {
            a[c * p + j] /= d;
            inv[c * p + j] /= d;
        }
        for (int r = 0; r < p; r++) {
            double f = a[r * p + c];
            if (r == c || f == 0.0)
                continue;
            for (int j = 0; j < p; j++) {
                a[r * p + j] -= f * a[c * p + j];
                inv[r * p + j] -= f * inv[c * p + j];
            }
        }
    }
    if (ok) {
        memcpy(cov, inv, (size_t)p * p * sizeof(double));
        for (int i = 0; i < p; i++) {
            double t = 0.0;
            for (int j = 0; j < p; j++)
                t += inv[i * p + j] * rhs[j];
            theta[i] = t;
        }
    }
    ret = PyBool_FromLong(ok);
done:
    while (nb-- > 0)
        PyBuffer_Release(&b[nb]);
    return ret;
}

/* fit_predict(h, theta, cov) -> (h' theta, h' cov h): a fit's prediction for regressors h and
 * its variance there (the glitch gate). */
static PyObject *k_fit_predict(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "fit_predict(h, theta, cov)");
        return NULL;
    }
    Py_buffer bh, bt, bc;
    double *h = get_doubles(args[0], &bh, -1, "h");
    if (!h)
        return NULL;
    Py_ssize_t p = bh.len / (Py_ssize_t)sizeof(double);
    PyObject *ret = NULL;
    double *th = get_doubles(args[1], &bt, p, "theta");
    if (!th)
        goto p_h;
    double *cv = get_doubles(args[2], &bc, p * p, "cov");
    if (!cv)
        goto p_t;
    double pred = 0.0, spread = 0.0;
    for (Py_ssize_t i = 0; i < p; i++) {
        pred += h[i] * th[i];
        double t = 0.0;
        for (Py_ssize_t j = 0; j < p; j++)
            t += h[j] * cv[j * p + i]; /* (h' cov)_i */
        spread += t * h[i];
    }
    ret = Py_BuildValue("(dd)", pred, spread);
    PyBuffer_Release(&bc);
p_t:
    PyBuffer_Release(&bt);
p_h:
    PyBuffer_Release(&bh);
    return ret;
}

/* ---- the latency identification's cost profile (latency.py) ------------------------------------
 * At every GNSS fix each timing reference fits y ~ a x + c . extra + b for each of its ~170
 * candidate delays from its forgotten sufficient statistics (p <= 8 regressors): two stacked
 * numpy solves and two einsums, most of a fix's latency work. Here each candidate's systems are
 * solved by Gaussian elimination with partial pivoting (LAPACK's dgesv does the same, in its own
 * summation order: the same math, not its last bits). */
#define LAT_MAX 8

/* Solve a x = b (a: m x m, row stride `stride`; b, x: m) by elimination with partial pivoting on
 * copies; 0 on an exactly zero pivot (numpy's LinAlgError: singular). */
static int small_solve(const double *a0, int stride, const double *b0, int m, double *x)
{
    double a[LAT_MAX * LAT_MAX], b[LAT_MAX];
    for (int i = 0; i < m; i++) {
        for (int j = 0; j < m; j++)
            a[i * m + j] = a0[i * stride + j];
        b[i] = b0[i];
    }
    for (int c = 0; c < m; c++) {
        int piv = c;
        for (int r = c + 1; r < m; r++)
            if (fabs(a[r * m + c]) > fabs(a[piv * m + c]))
                piv = r;
        if (a[piv * m + c] == 0.0)
            return 0;
        if (piv != c) {
            for (int j = 0; j < m; j++) {
                double t = a[c * m + j];
                a[c * m + j] = a[piv * m + j];
                a[piv * m + j] = t;
            }
            double t = b[c];
            b[c] = b[piv];
            b[piv] = t;
        }
        for (int r = c + 1; r < m; r++) {
            double l = a[r * m + c] / a[c * m + c];
            for (int j = c + 1; j < m; j++)
                a[r * m + j] -= l * a[c * m + j];
            b[r] -= l * b[c];
        }
    }
    for (int i = m - 1; i >= 0; i--) {
        double v = b[i];
        for (int j = i + 1; j < m; j++)
            v -= a[i * m + j] * x[j];
        x[i] = v / a[i * m + i];
    }
    return 1;
}

/* latency_costs(zz, zy, syy, floor, c) -> informative: per candidate k, the regressor's variation
 * the other columns do not explain, cxx_k = zz_k[0,0] - zz_k[0,1:] zz_k[1:,1:]^-1 zz_k[1:,0]; False
 * (c untouched) unless every cxx_k > floor; else c_k = max(syy - theta_k' zy_k, 0) with
 * theta_k = zz_k^-1 zy_k, the residual sum of squares of candidate k's fit. */
static PyObject *k_latency_costs(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "latency_costs(zz, zy, syy, floor, c)");
        return NULL;
    }
    double syy = PyFloat_AsDouble(args[2]), floor_ = PyFloat_AsDouble(args[3]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bzz, bzy, bc;
    PyObject *ret = NULL;
    double *c = get_doubles(args[4], &bc, -1, "c");
    if (!c)
        return NULL;
    Py_ssize_t n = bc.len / (Py_ssize_t)sizeof(double);
    double *zy = get_doubles(args[1], &bzy, -n, "zy");
    if (!zy)
        goto l_c;
    Py_ssize_t p = bzy.len / (Py_ssize_t)sizeof(double) / n;
    if (p < 2 || p > LAT_MAX) {
        PyErr_SetString(PyExc_ValueError, "latency_costs: 2 to 8 regressors");
        goto l_zy;
    }
    double *zz = get_doubles(args[0], &bzz, n * p * p, "zz");
    if (!zz)
        goto l_zy;
    double sol[LAT_MAX];
    int informative = 1;
    for (Py_ssize_t k = 0; k < n && informative; k++) {
        const double *z = zz + k * p * p;
        double rhs[LAT_MAX];
        for (int i = 1; i < p; i++)
            rhs[i - 1] = z[i * p];
        if (!small_solve(z + p + 1, (int)p, rhs, (int)p - 1, sol)) {
            PyErr_SetString(PyExc_ValueError, "latency_costs: singular statistics");
            goto l_zz;
        }
        double v = 0.0;
        for (int i = 1; i < p; i++)
            v += z[i] * sol[i - 1];
        informative = z[0] - v > floor_;
    }
    if (informative) {
        for (Py_ssize_t k = 0; k < n; k++) {
            if (!small_solve(zz + k * p * p, (int)p, zy + k * p, (int)p, sol)) {
                PyErr_SetString(PyExc_ValueError, "latency_costs: singular statistics");
                goto l_zz;
            }
            double v = 0.0;
            for (int i = 0; i < p; i++)
                v += sol[i] * zy[k * p + i];
            double r = syy - v;
            c[k] = r > 0.0 || r != r ? r : 0.0; /* np.maximum(r, 0): NaN stays NaN */
        }
    }
    ret = PyBool_FromLong(informative);
l_zz:
    PyBuffer_Release(&bzz);
l_zy:
    PyBuffer_Release(&bzy);
l_c:
    PyBuffer_Release(&bc);
    return ret;
}

/* accumulate(zz, zy, x, extra, y, lam): one fix into the latency identification's forgotten
 * sufficient statistics, in place, for every candidate k with z_k = [x_k, extra..., 1]:
 * zz_k <- lam zz_k + z_k z_k', zy_k <- lam zy_k + z_k y. The same elementwise operations, in the
 * same order, as accumulate_reference's numpy (a product and a sum per entry, no reduction), so
 * the same bits; what goes is the per-fix stack, outer product and four temporaries.
 * x: float64, 1-D, any stride (a column of the history); zz, zy: C-contiguous. */
static PyObject *k_accumulate(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 6 || !PyTuple_Check(args[3])) {
        PyErr_SetString(PyExc_TypeError, "accumulate(zz, zy, x, extra: tuple, y, lam)");
        return NULL;
    }
    double y = PyFloat_AsDouble(args[4]), lam = PyFloat_AsDouble(args[5]);
    if (PyErr_Occurred())
        return NULL;
    Py_ssize_t ne = PyTuple_GET_SIZE(args[3]);
    Py_ssize_t p = ne + 2;
    if (p > LAT_MAX) {
        PyErr_SetString(PyExc_ValueError, "accumulate: 2 to 8 regressors");
        return NULL;
    }
    double z[LAT_MAX];
    for (Py_ssize_t i = 0; i < ne; i++) {
        z[1 + i] = PyFloat_AsDouble(PyTuple_GET_ITEM(args[3], i));
        if (z[1 + i] == -1.0 && PyErr_Occurred())
            return NULL;
    }
    z[p - 1] = 1.0;
    Py_buffer bx, bzz, bzy;
    PyObject *ret = NULL;
    if (PyObject_GetBuffer(args[2], &bx, PyBUF_STRIDES | PyBUF_FORMAT) < 0)
        return NULL;
    if (bx.ndim != 1 || bx.itemsize != sizeof(double) || strcmp(bx.format, "d") != 0) {
        PyErr_SetString(PyExc_ValueError, "accumulate: x must be a 1-D float64 array");
        goto l_x;
    }
    Py_ssize_t n = bx.shape[0], sx = bx.strides[0];
    double *zz = get_doubles(args[0], &bzz, n * p * p, "zz");
    if (!zz)
        goto l_x;
    double *zy = get_doubles(args[1], &bzy, n * p, "zy");
    if (!zy)
        goto l_zz;
    const char *xb = (const char *)bx.buf;
    for (Py_ssize_t k = 0; k < n; k++) {
        z[0] = *(const double *)(xb + k * sx);
        double *a = zz + k * p * p, *b = zy + k * p;
        for (Py_ssize_t i = 0; i < p; i++) {
            for (Py_ssize_t j = 0; j < p; j++)
                a[i * p + j] = lam * a[i * p + j] + z[i] * z[j];
            b[i] = lam * b[i] + z[i] * y;
        }
    }
    Py_INCREF(Py_None);
    ret = Py_None;
    PyBuffer_Release(&bzy);
l_zz:
    PyBuffer_Release(&bzz);
l_x:
    PyBuffer_Release(&bx);
    return ret;
}

/* shift_statistics(zz, zy, offsets) -> done: LatencyEstimator.shift's re-anchoring of the
 * statistics, zz_k <- M zz_k M' and zy_k <- M zy_k for every candidate k (M the identity less the
 * offsets in its last column), in place, with the bits of the two einsums it replaces: each entry
 * is 0.0 plus its nonzero products in einsum's order (M's column j outer, l inner), each product
 * multiplied left to right (shift_statistics_reference, latency.py: why that is einsum's sum).
 * False (nothing written) unless every statistic and offset is finite, as the reference.
 * zz (n, p, p), zy (n, p): C-contiguous float64; offsets: a tuple of p - 1 floats. */
static PyObject *k_shift_statistics(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3 || !PyTuple_Check(args[2])) {
        PyErr_SetString(PyExc_TypeError, "shift_statistics(zz, zy, offsets: tuple)");
        return NULL;
    }
    Py_ssize_t p = PyTuple_GET_SIZE(args[2]) + 1;
    if (p < 2 || p > LAT_MAX) {
        PyErr_SetString(PyExc_ValueError, "shift_statistics: 2 to 8 regressors");
        return NULL;
    }
    double no[LAT_MAX];
    int finite = 1;
    for (Py_ssize_t i = 0; i < p - 1; i++) {
        double o = PyFloat_AsDouble(PyTuple_GET_ITEM(args[2], i));
        if (o == -1.0 && PyErr_Occurred())
            return NULL;
        finite = finite && isfinite(o);
        no[i] = -o;
    }
    no[p - 1] = -0.0;
    Py_buffer bzz, bzy;
    PyObject *ret = NULL;
    double *zz = get_doubles(args[0], &bzz, -(p * p), "zz");
    if (!zz)
        return NULL;
    Py_ssize_t n = bzz.len / (Py_ssize_t)sizeof(double) / (p * p);
    double *zy = get_doubles(args[1], &bzy, n * p, "zy");
    if (!zy)
        goto l_zz;
    for (Py_ssize_t k = 0; finite && k < n * p * p; k++)
        finite = isfinite(zz[k]);
    for (Py_ssize_t k = 0; finite && k < n * p; k++)
        finite = isfinite(zy[k]);
    if (finite) {
        const Py_ssize_t q = p - 1;
        double t[LAT_MAX * LAT_MAX];
        for (Py_ssize_t k = 0; k < n; k++) {
            double *a = zz + k * p * p, *b = zy + k * p;
            for (Py_ssize_t i = 0; i < p; i++)
                for (Py_ssize_t m = 0; m < p; m++) {
                    double v = 0.0 + a[i * p + m];
                    v = v + a[i * p + q] * no[m];
                    v = v + no[i] * a[q * p + m];
                    v = v + (no[i] * a[q * p + q]) * no[m];
                    t[i * p + m] = v;
                }
            memcpy(a, t, (size_t)(p * p) * sizeof(double));
            double bq = b[q];
            for (Py_ssize_t i = 0; i < p; i++)
                b[i] = (0.0 + b[i]) + no[i] * bq;
        }
    }
    ret = PyBool_FromLong(finite);
    PyBuffer_Release(&bzy);
l_zz:
    PyBuffer_Release(&bzz);
    return ret;
}

/* latency_window(X, aux, P, last, lever_x, slip, min_speed, x_out, rate_out) -> vy error or None:
 * LatencyEstimator.observe's per-fix window over its candidate delays m = 0..count-1 (count =
 * len(x_out)), history slot (last - m) mod n, as latency_window_reference computes it with numpy:
 * None (outputs unspecified) if a wheel speed is not finite or below min_speed; else the wheel
 * speeds into x_out (divided by 1 + slip rate unless slip is None), the speed's rate
 * (vx ax + vy ay) / max(|v|, 1) into rate_out, and max over the window of |vy + r lever_x| sqrt(max(P_vy,vy, 0))
 * (NaN if any is). Elementwise, each operation numpy's (hypot is libm's in both), so the same bits;
 * what goes is the gathers of whole history rows and ~15 numpy calls of ~160 values per fix.
 * Columns: X's VX 0, VY 1 (kinematic.py); aux's AUX_R 0, AUX_AY 1, AUX_WHEEL 3, AUX_AX 5 (history.py). */
static PyObject *k_latency_window(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 9) {
        PyErr_SetString(PyExc_TypeError,
                        "latency_window(X, aux, P, last, lever_x, slip, min_speed, x_out, rate_out)");
        return NULL;
    }
    long long last = PyLong_AsLongLong(args[3]);
    double lever_x = PyFloat_AsDouble(args[4]);
    int use_slip = args[5] != Py_None;
    double slip = use_slip ? PyFloat_AsDouble(args[5]) : 0.0;
    double min_speed = PyFloat_AsDouble(args[6]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bX, ba, bP, bx, br;
    PyObject *ret = NULL;
    double *X = get_doubles(args[0], &bX, -N, "X");
    if (!X)
        return NULL;
    Py_ssize_t n = bX.len / (Py_ssize_t)sizeof(double) / N;
    double *aux = get_doubles(args[1], &ba, -n, "aux");
    if (!aux)
        goto l_X;
    Py_ssize_t na = ba.len / (Py_ssize_t)sizeof(double) / n;
    if (na < 6) {
        PyErr_SetString(PyExc_ValueError, "latency_window: aux needs 6 columns");
        goto l_a;
    }
    double *P = get_doubles(args[2], &bP, n * N * N, "P");
    if (!P)
        goto l_a;
    double *x = get_doubles(args[7], &bx, -1, "x_out");
    if (!x)
        goto l_P;
    Py_ssize_t count = bx.len / (Py_ssize_t)sizeof(double);
    double *rate = get_doubles(args[8], &br, count, "rate_out");
    if (!rate)
        goto l_x;
    int ok = 1;
    for (Py_ssize_t m = 0; m < count; m++) {
        long long s = (last - m) % n;
        const double w = aux[(s < 0 ? s + n : s) * na + 3];
        if (!isfinite(w) || w < min_speed) {
            ok = 0;
            break;
        }
        x[m] = w;
    }
    if (!ok) {
        Py_INCREF(Py_None);
        ret = Py_None;
        goto l_r;
    }
    double worst = -INFINITY;
    int nan = 0;
    for (Py_ssize_t m = 0; m < count; m++) {
        long long s = (last - m) % n;
        if (s < 0)
            s += n;
        const double *a = aux + s * na, *xs = X + s * N;
        const double vx = xs[0], vy = xs[1];
        double h = hypot(vx, vy);
        h = (h != h || h >= 1.0) ? h : 1.0;  /* np.maximum(h, 1.0): NaN propagates */
        const double r = (vx * a[5] + vy * a[1]) / h;
        rate[m] = r;
        if (use_slip)
            x[m] = x[m] / (1.0 + slip * r);
        double pv = P[s * N * N + 1 * N + 1];
        pv = (pv != pv || pv >= 0.0) ? pv : 0.0;
        const double e = fabs(vy + a[0] * lever_x) * sqrt(pv);
        if (e != e)
            nan = 1;
        else if (e > worst)
            worst = e;
    }
    ret = PyFloat_FromDouble(nan ? NAN : worst);
l_r:
    PyBuffer_Release(&br);
l_x:
    PyBuffer_Release(&bx);
l_P:
    PyBuffer_Release(&bP);
l_a:
    PyBuffer_Release(&ba);
l_X:
    PyBuffer_Release(&bX);
    return ret;
}

/* speed_window(v, vel, last, total, lever_x, lever_y, out): SpeedIntegral.observe's regressor at
 * every candidate m = 0..len(out)-1 (ring slot (last - m) mod n): the integral less its anchor,
 * (v_s - total), plus the antenna's lever-arm speed hypot(vx - r ly, vy + r lx) - hypot(vx, vy),
 * as speed_window_reference's numpy: elementwise, the same operations (hypot libm's in both), the
 * same bits; without its gathers and ~10 numpy calls a fix. v (n,), vel (n, 3): C-contiguous. */
static PyObject *k_speed_window(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 7) {
        PyErr_SetString(PyExc_TypeError, "speed_window(v, vel, last, total, lever_x, lever_y, out)");
        return NULL;
    }
    long long last = PyLong_AsLongLong(args[2]);
    double total = PyFloat_AsDouble(args[3]), lx = PyFloat_AsDouble(args[4]), ly = PyFloat_AsDouble(args[5]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer bv, bvel, bo;
    PyObject *ret = NULL;
    double *v = get_doubles(args[0], &bv, -1, "v");
    if (!v)
        return NULL;
    Py_ssize_t n = bv.len / (Py_ssize_t)sizeof(double);
    double *vel = get_doubles(args[1], &bvel, n * 3, "vel");
    if (!vel)
        goto l_v;
    double *out = get_doubles(args[6], &bo, -1, "out");
    if (!out)
        goto l_vel;
    Py_ssize_t count = bo.len / (Py_ssize_t)sizeof(double);
    for (Py_ssize_t m = 0; m < count; m++) {
        long long s = (last - m) % n;
        if (s < 0)
            s += n;
        const double vx = vel[s * 3], vy = vel[s * 3 + 1], r = vel[s * 3 + 2];
        const double lp = hypot(vx - r * ly, vy + r * lx) - hypot(vx, vy);
        out[m] = (v[s] - total) + lp;
    }
    Py_INCREF(Py_None);
    ret = Py_None;
    PyBuffer_Release(&bo);
l_vel:
    PyBuffer_Release(&bvel);
l_v:
    PyBuffer_Release(&bv);
    return ret;
}

/* median(c) -> numpy.median of a 1-D float64 array (NaN if it holds one), as a float: the
 * latency profile's "very clear minimum" test at every profile. numpy's is ~10 us of Python
 * (partition, mean, NaN check) for ~170 values; the result is a selection, or for an even count
 * the two middle values as np.mean adds and divides them (a + (0 + b)) / 2: the same bits. */
static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* refine_scan(lr, share, reject, cur) -> None or (i, y0, y1, y2, first, last, at_cur): LatencyEstimator._refine's
   scan of its summed profile (latency.refine_scan_reference: the numpy it replaces): i numpy's argmin (the first
   minimum; the first NaN if any), None at either end; else d = lr - lr[i] at i - 1, i, i + 1, the first and last
   k with share * d[k] < reject (IndexError if none, as numpy's empty flatnonzero()[0]) and d[cur]. The same
   elementwise operations, without the profile's temporaries and ~12 numpy calls a refinement. */
static PyObject *k_refine_scan(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4) {
        PyErr_SetString(PyExc_TypeError, "refine_scan(lr, share, reject, cur)");
        return NULL;
    }
    double share = PyFloat_AsDouble(args[1]);
    double reject = PyFloat_AsDouble(args[2]);
    Py_ssize_t cur = PyLong_AsSsize_t(args[3]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer b;
    double *lr = get_doubles(args[0], &b, -1, "lr");
    if (!lr)
        return NULL;
    Py_ssize_t n = b.len / (Py_ssize_t)sizeof(double);
    PyObject *ret = NULL;
    if (cur < 0 || cur >= n) {
        PyErr_SetString(PyExc_IndexError, "refine_scan: cur out of bounds");
        goto done;
    }
    Py_ssize_t i = 0;
    double best = lr[0];
    if (best == best) {
        for (Py_ssize_t k = 1; k < n; k++) {
            const double v = lr[k];
            if (v != v) {  /* numpy's argmin: the first NaN */
                i = k;
                break;
            }
            if (v < best) {
                best = v;
                i = k;
            }
        }
    }
    if (i == 0 || i == n - 1) {
        Py_INCREF(Py_None);
        ret = Py_None;
        goto done;
    }
    const double lo = lr[i];
    Py_ssize_t first = -1, last = -1;
    for (Py_ssize_t k = 0; k < n; k++) {
        const double d = lr[k] - lo;
        if (share * d < reject) {
            if (first < 0)
                first = k;
            last = k;
        }
    }
    if (first < 0) {
        PyErr_SetString(PyExc_IndexError, "index 0 is out of bounds for axis 0 with size 0");
        goto done;
    }
    ret = Py_BuildValue("(ndddnnd)", i, lr[i - 1] - lo, lr[i] - lo, lr[i + 1] - lo, first, last, lr[cur] - lo);
done:
    PyBuffer_Release(&b);
    return ret;
}

static PyObject *k_median(PyObject *self, PyObject *arg)
{
    Py_buffer b;
    if (PyObject_GetBuffer(arg, &b, PyBUF_STRIDES | PyBUF_FORMAT) < 0)
        return NULL;
    if (b.ndim != 1 || b.itemsize != sizeof(double) || strcmp(b.format, "d") != 0 || b.shape[0] == 0) {
        PyErr_SetString(PyExc_ValueError, "median: a non-empty 1-D float64 array");
        PyBuffer_Release(&b);
        return NULL;
    }
    Py_ssize_t n = b.shape[0], s = b.strides[0];
    double stack[512], *v = n <= 512 ? stack : PyMem_Malloc(n * sizeof(double));
    if (!v) {
        PyBuffer_Release(&b);
        return PyErr_NoMemory();
    }
    double med;
    int nan = 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        v[k] = *(const double *)((const char *)b.buf + k * s);
        nan |= v[k] != v[k];
    }
    PyBuffer_Release(&b);
    if (nan) {
        med = NAN;
    } else {
        qsort(v, (size_t)n, sizeof(double), cmp_double);
        med = n % 2 ? v[n / 2] : (v[n / 2 - 1] + (0.0 + v[n / 2])) / 2.0;
    }
    if (v != stack)
        PyMem_Free(v);
    return PyFloat_FromDouble(med);
}

/* reduction_rank(M) -> the number of terms correct() carries M through (-1: M whole); for tests. */
static PyObject *k_reduction_rank(PyObject *self, PyObject *arg)
{
    Py_buffer b;
    double *M = get_doubles(arg, &b, N * N, "M");
    if (!M)
        return NULL;
    double U[LOWRANK_MAX * N], D[LOWRANK_MAX];
    int r = lowrank_factor(M, U, D);
    PyBuffer_Release(&b);
    return PyLong_FromLong(r);
}

static PyMethodDef methods[] = {
    {"predict", (PyCFunction)(void (*)(void))k_predict, METH_FASTCALL,
     "predict(x, P, P_out, F, q, r_m, ax_m, ay_m, dt): one model step in place"},
    {"predict_from", (PyCFunction)(void (*)(void))k_predict_from, METH_FASTCALL,
     "predict_from(x_prev, x, P_prev, P_out, F, A, q, r_m, ax_m, ay_m, dt): x <- x_prev, predict, A <- F"},
    {"scalar_update", (PyCFunction)(void (*)(void))k_scalar_update, METH_FASTCALL,
     "scalar_update(x, P, innovation, h, R, gate_sigma=0.0, A=None) -> fused"},
    {"index_update", (PyCFunction)(void (*)(void))k_index_update, METH_FASTCALL,
     "index_update(x, P, innovation, i, R, gate_sigma=0.0, A=None) -> fused"},
    {"symmetrize", k_symmetrize, METH_O, "symmetrize(P): P <- (P + P') / 2 in place"},
    {"correct", (PyCFunction)(void (*)(void))k_correct, METH_FASTCALL,
     "correct(X, P, A, s, last, dx, M) -> applied (False: a covariance would not be positive definite)"},
    {"late_update", (PyCFunction)(void (*)(void))k_late_update, METH_FASTCALL,
     "late_update(P, H, R, y, dx, M) -> NIS; dx = K y, M = P - Joseph(P) (NaN: S not positive definite)"},
    {"rls_update", (PyCFunction)(void (*)(void))k_rls_update, METH_FASTCALL,
     "rls_update(k, P, P0, phi, n2, y, rv, lam) -> e: the single-track compliance learner's RLS step"},
    {"reduction_rank", k_reduction_rank, METH_O,
     "reduction_rank(M) -> terms of the low-rank factor correct() carries M through (-1: M whole)"},
    {"positive_definite", k_positive_definite, METH_O,
     "positive_definite(P) -> every 8x8 matrix of the stack is finite and positive definite"},
    {"axle_propagate", (PyCFunction)(void (*)(void))k_axle_propagate, METH_FASTCALL,
     "axle_propagate(P, c, q_psi, q_bias): a stiffness-regression axle's heading propagation in place"},
    {"axle_update", (PyCFunction)(void (*)(void))k_axle_update, METH_FASTCALL,
     "axle_update(x, P, z, h, rv) -> normalised innovation (latency considered, Joseph form)"},
    {"axle_latency", (PyCFunction)(void (*)(void))k_axle_latency, METH_FASTCALL,
     "axle_latency(x, P, tau, var): move the considered latency, the states through their covariance"},
    {"gyro_sum", (PyCFunction)(void (*)(void))k_gyro_sum, METH_FASTCALL,
     "gyro_sum(aux, r_col, X, br_col, k0, k1) -> sum of aux[k, r_col] + X[k, br_col], k0 <= k <= k1"},
    {"yaw_sum", (PyCFunction)(void (*)(void))k_yaw_sum, METH_FASTCALL,
     "yaw_sum(aux, r_col, k0, k1, ring) -> np.sum of aux[k, r_col] (/ (1 - ring[k])), k0 <= k <= k1, numpy's bits"},
    {"window_fit", (PyCFunction)(void (*)(void))k_window_fit, METH_FASTCALL,
     "window_fit(aux, r_col, ay_col, lo, hi, s, dt) -> (r_dot, r, ay mean, its standard error)"},
    {"sens_step", (PyCFunction)(void (*)(void))k_sens_step, METH_FASTCALL,
     "sens_step(A, S_prev, S_out): S_out = A S_prev (the latency sensitivity through one step)"},
    {"sens_fused", (PyCFunction)(void (*)(void))k_sens_fused, METH_FASTCALL,
     "sens_fused(S, A, P, H, R, h, s, last): S_s -= K (H S_s - h), then carried to step last"},
    {"prefix_doubling", k_prefix_doubling, METH_O,
     "prefix_doubling(phis): phis[j] <- phis[j] ... phis[0] in place (count x 8 x 8), numpy's bits where checked"},
    {"carry_change", (PyCFunction)(void (*)(void))k_carry_change, METH_FASTCALL,
     "carry_change(S, A, s, last, delta): S at steps s+1 .. last += (A_j ... A_{s+1}) delta, numpy's bits"},
    {"scale_step", (PyCFunction)(void (*)(void))k_scale_step, METH_FASTCALL,
     "scale_step(A, S_prev, S_out, i, r_dt): S_out = A S_prev, S_out[i] += r_dt, numpy's bits"},
    {"scale_fused", (PyCFunction)(void (*)(void))k_scale_fused, METH_FASTCALL,
     "scale_fused(S, A, P, H, R, s, last): S_s += delta = -K H S_s, carried to step last one step at a time"},
    {"across_secant", (PyCFunction)(void (*)(void))k_across_secant, METH_FASTCALL,
     "across_secant(aux, c, sn, u0, u1, lever_x, lever_y, dt, i0, span, slope) -> the timing secant of the across-track acceleration"},
    {"fit_update", (PyCFunction)(void (*)(void))k_fit_update, METH_FASTCALL,
     "fit_update(info, rhs, h, z, var, prior, theta, cov) -> solved: add a fix, solve the regularised fit"},
    {"fit_predict", (PyCFunction)(void (*)(void))k_fit_predict, METH_FASTCALL,
     "fit_predict(h, theta, cov) -> (h' theta, h' cov h)"},
    {"latency_costs", (PyCFunction)(void (*)(void))k_latency_costs, METH_FASTCALL,
     "latency_costs(zz, zy, syy, floor, c) -> informative: each candidate delay's residual sum of squares"},
    {"accumulate", (PyCFunction)(void (*)(void))k_accumulate, METH_FASTCALL,
     "accumulate(zz, zy, x, extra, y, lam): one fix into the latency identification's statistics, in place"},
    {"refine_scan", (PyCFunction)(void (*)(void))k_refine_scan, METH_FASTCALL,
     "refine_scan(lr, share, reject, cur) -> None or (i, y0, y1, y2, first, last, at_cur): _refine's profile scan"},
    {"median", k_median, METH_O, "median(c) -> numpy.median of a 1-D float64 array, as a float"},
    {"shift_statistics", (PyCFunction)(void (*)(void))k_shift_statistics, METH_FASTCALL,
     "shift_statistics(zz, zy, offsets) -> done: the latency statistics re-anchored in place, einsum's bits"},
    {"latency_window", (PyCFunction)(void (*)(void))k_latency_window, METH_FASTCALL,
     "latency_window(X, aux, P, last, lever_x, slip, min_speed, x_out, rate_out) -> vy error or None: observe's window"},
    {"speed_window", (PyCFunction)(void (*)(void))k_speed_window, METH_FASTCALL,
     "speed_window(v, vel, last, total, lever_x, lever_y, out): SpeedIntegral.observe's regressors"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernels", "Compiled estimator kernels (see _kernels.c).", -1, methods,
};

PyMODINIT_FUNC PyInit__kernels(void)
{
    return PyModule_Create(&module);
}
