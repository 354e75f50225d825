/* fdi_linalg.c - block carving, exact summation and the matrix exponential (C99, no allocation).
 *
 * fdi_expm mirrors fmu_fdi/runtime/expm.py operation by operation: scaling and squaring with
 * the [13/13] Pade approximant (Higham, "The scaling and squaring method for the matrix
 * exponential revisited", SIAM J. Matrix Anal. Appl. 26, 2005); the linear solve is an LU
 * factorisation with partial pivoting (as LAPACK dgesv). fdi_fsum is Python's math.fsum
 * (Shewchuk, "Adaptive precision floating-point arithmetic", 1997), correctly rounded.
 */
#include <math.h>
#include <string.h>

#include "fdi_internal.h"

void *fdi_carve(fdi_carver *c, size_t bytes)
{
    size_t off = (c->off + 15u) & ~(size_t)15u;
    c->off = off + bytes;
    return c->base ? (void *)(c->base + off) : NULL;
}

double *fdi_slot_d(fdi_slots *s, size_t n)
{
    double *p = s->d ? s->d + s->nd : NULL;
    s->nd += n;
    return p;
}

fdi_int *fdi_slot_i(fdi_slots *s, size_t n)
{
    fdi_int *p = s->i ? s->i + s->ni : NULL;
    s->ni += n;
    return p;
}

unsigned char *fdi_slot_b(fdi_slots *s, size_t n)
{
    unsigned char *p = s->b ? s->b + s->nb : NULL;
    s->nb += n;
    return p;
}

void fdi_matvec(const double *M, long rows, long cols, const double *x, double *y)
{
    /* Four rows at a time: independent accumulators hide the add latency, while every row is
     * still summed in column order (the same rounding as one row at a time). */
    long i = 0, j;
    for (; i + 4 <= rows; i += 4) {
        const double *r0 = M + (size_t)i * (size_t)cols, *r1 = r0 + cols, *r2 = r1 + cols, *r3 = r2 + cols;
        double a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
        for (j = 0; j < cols; j++) {
            double xj = x[j];
            a0 += r0[j] * xj;
            a1 += r1[j] * xj;
            a2 += r2[j] * xj;
            a3 += r3[j] * xj;
        }
        y[i] = a0;
        y[i + 1] = a1;
        y[i + 2] = a2;
        y[i + 3] = a3;
    }
    for (; i < rows; i++) {
        const double *row = M + (size_t)i * (size_t)cols;
        double acc = 0.0;
        for (j = 0; j < cols; j++)
            acc += row[j] * x[j];
        y[i] = acc;
    }
}

/* ------------------------------------------------------------------ fsum */
#define FDI_FSUM_PARTIALS 64  /* non-overlapping doubles: at most ~40 are ever needed */

double fdi_fsum(const double *xs, long count)
{
    double p[FDI_FSUM_PARTIALS];
    double x, y, t, hi, yr, lo = 0.0;
    long k;
    int i, j, n = 0;
    for (k = 0; k < count; k++) {
        double xsave = xs[k];
        x = xsave;
        for (i = j = 0; j < n; j++) {
            y = p[j];
            if (fabs(x) < fabs(y)) {
                t = x;
                x = y;
                y = t;
            }
            hi = x + y;
            yr = hi - x;
            lo = y - yr;
            if (lo != 0.0)
                p[i++] = lo;
            x = hi;
        }
        n = i;
        if (x != 0.0) {
            if (!isfinite(x))
                return x;  /* intermediate overflow or a non-finite summand: the caller resets */
            if (n < FDI_FSUM_PARTIALS)
                p[n++] = x;
        }
    }
    hi = 0.0;
    if (n > 0) {
        hi = p[--n];
        while (n > 0) {
            x = hi;
            y = p[--n];
            hi = x + y;
            yr = hi - x;
            lo = y - yr;
            if (lo != 0.0)
                break;
        }
        if (n > 0 && ((lo < 0.0 && p[n - 1] < 0.0) || (lo > 0.0 && p[n - 1] > 0.0))) {
            y = lo * 2.0;
            x = hi + y;
            yr = x - hi;
            if (y == yr)
                hi = x;
        }
    }
    return hi;
}

/* ------------------------------------------------------------------ matrix exponential */
static void matmul(const double *A, const double *B, long n, double *C)
{
    long i, j, k;
    for (i = 0; i < n; i++) {
        double *c = C + (size_t)i * (size_t)n;
        for (j = 0; j < n; j++)
            c[j] = 0.0;
        for (k = 0; k < n; k++) {
            double a = A[(size_t)i * (size_t)n + (size_t)k];
            const double *b = B + (size_t)k * (size_t)n;
            for (j = 0; j < n; j++)
                c[j] += a * b[j];
        }
    }
}

/* Solve P X = Q in place (X overwrites Q) by LU with partial pivoting; 0 if P is singular. */
static int lu_solve(double *P, double *Q, long n)
{
    long i, j, k;
    for (k = 0; k < n; k++) {
        long piv = k;
        double best = fabs(P[(size_t)k * (size_t)n + (size_t)k]);
        for (i = k + 1; i < n; i++) {
            double a = fabs(P[(size_t)i * (size_t)n + (size_t)k]);
            if (a > best) {
                best = a;
                piv = i;
            }
        }
        if (!(best > 0.0) || !isfinite(best))
            return 0;
        if (piv != k) {
            for (j = 0; j < n; j++) {
                double t = P[(size_t)k * (size_t)n + (size_t)j];
                P[(size_t)k * (size_t)n + (size_t)j] = P[(size_t)piv * (size_t)n + (size_t)j];
                P[(size_t)piv * (size_t)n + (size_t)j] = t;
                t = Q[(size_t)k * (size_t)n + (size_t)j];
                Q[(size_t)k * (size_t)n + (size_t)j] = Q[(size_t)piv * (size_t)n + (size_t)j];
                Q[(size_t)piv * (size_t)n + (size_t)j] = t;
            }
        }
        for (i = k + 1; i < n; i++) {
            double l = P[(size_t)i * (size_t)n + (size_t)k] / P[(size_t)k * (size_t)n + (size_t)k];
            P[(size_t)i * (size_t)n + (size_t)k] = l;
            for (j = k + 1; j < n; j++)
                P[(size_t)i * (size_t)n + (size_t)j] -= l * P[(size_t)k * (size_t)n + (size_t)j];
            for (j = 0; j < n; j++)
                Q[(size_t)i * (size_t)n + (size_t)j] -= l * Q[(size_t)k * (size_t)n + (size_t)j];
        }
    }
    for (k = n - 1; k >= 0; k--) {
        double pkk = P[(size_t)k * (size_t)n + (size_t)k];
        for (j = 0; j < n; j++) {
            double acc = Q[(size_t)k * (size_t)n + (size_t)j];
            for (i = k + 1; i < n; i++)
                acc -= P[(size_t)k * (size_t)n + (size_t)i] * Q[(size_t)i * (size_t)n + (size_t)j];
            Q[(size_t)k * (size_t)n + (size_t)j] = acc / pkk;
        }
    }
    return 1;
}

static const double B13[14] = {
    64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
    129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
    40840800.0, 960960.0, 16380.0, 182.0, 1.0};
static const double THETA13 = 5.371920351148152;

#define FDI_EXPM_MATS 8

int fdi_expm(const double *A0, long n, double *E, double *work)
{
    size_t nn = (size_t)n * (size_t)n, q;
    double *A = work, *A2 = A + nn, *A4 = A2 + nn, *A6 = A4 + nn, *T = A6 + nn, *U = T + nn, *V = U + nn,
           *W = V + nn;
    double norm = 0.0, scale;
    long i, j, s = 0;
    if (n == 0)
        return 1;
    for (j = 0; j < n; j++) {
        double col = 0.0;
        for (i = 0; i < n; i++)
            col += fabs(A0[(size_t)i * (size_t)n + (size_t)j]);
        if (col > norm)
            norm = col;
    }
    if (!isfinite(norm))
        return 0;
    if (norm > THETA13) {
        double l = ceil(log2(norm / THETA13));
        s = l > 0.0 ? (long)l : 0;
    }
    scale = ldexp(1.0, (int)s);
    for (q = 0; q < nn; q++)
        A[q] = A0[q] / scale;
    matmul(A, A, n, A2);
    matmul(A2, A2, n, A4);
    matmul(A4, A2, n, A6);
    for (q = 0; q < nn; q++)
        T[q] = B13[13] * A6[q] + B13[11] * A4[q] + B13[9] * A2[q];
    matmul(A6, T, n, W);
    for (q = 0; q < nn; q++)
        W[q] = W[q] + B13[7] * A6[q] + B13[5] * A4[q] + B13[3] * A2[q];
    for (i = 0; i < n; i++)
        W[(size_t)i * (size_t)n + (size_t)i] += B13[1];
    matmul(A, W, n, U);
    for (q = 0; q < nn; q++)
        T[q] = B13[12] * A6[q] + B13[10] * A4[q] + B13[8] * A2[q];
    matmul(A6, T, n, V);
    for (q = 0; q < nn; q++)
        V[q] = V[q] + B13[6] * A6[q] + B13[4] * A4[q] + B13[2] * A2[q];
    for (i = 0; i < n; i++)
        V[(size_t)i * (size_t)n + (size_t)i] += B13[0];
    for (q = 0; q < nn; q++) {
        T[q] = V[q] - U[q];   /* P */
        W[q] = V[q] + U[q];   /* Q, becomes E */
    }
    if (!lu_solve(T, W, n))
        return 0;
    for (i = 0; i < s; i++) {
        matmul(W, W, n, T);
        memcpy(W, T, nn * sizeof(double));
    }
    for (q = 0; q < nn; q++) {
        if (!isfinite(W[q]))
            return 0;
        E[q] = W[q];
    }
    return 1;
}

size_t fdi_zoh_work(long n, long m)
{
    size_t N = (size_t)(n + m);
    return (FDI_EXPM_MATS + 2) * N * N;
}

int fdi_zoh(const double *A, const double *B, long n, long m, double h, double *Ad, double *Bd, double *work)
{
    long N = n + m, i, j;
    size_t NN = (size_t)N * (size_t)N;
    double *Mz = work, *E = work + NN, *w = work + 2 * NN;
    memset(Mz, 0, NN * sizeof(double));
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++)
            Mz[(size_t)i * (size_t)N + (size_t)j] = A[(size_t)i * (size_t)n + (size_t)j] * h;
        for (j = 0; j < m; j++)
            Mz[(size_t)i * (size_t)N + (size_t)(n + j)] = B[(size_t)i * (size_t)m + (size_t)j] * h;
    }
    if (!fdi_expm(Mz, N, E, w))
        return 0;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++)
            Ad[(size_t)i * (size_t)n + (size_t)j] = E[(size_t)i * (size_t)N + (size_t)j];
        for (j = 0; j < m; j++)
            Bd[(size_t)i * (size_t)m + (size_t)j] = E[(size_t)i * (size_t)N + (size_t)(n + j)];
    }
    return 1;
}
