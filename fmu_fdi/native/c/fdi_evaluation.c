/* fdi_evaluation.c - residual evaluation functions and decision thresholds, per sample.
 *
 * Line by line the rules of fmu_fdi/runtime/evaluation.py and thresholds.py (Frank 1990,
 * sec. 7; Basseville & Nikiforov 1993), with the same floating-point operations in the same
 * order wherever the Python code is scalar:
 *   norm      J = ||r||
 *   rms       J = sqrt(max(S, 0) / N), S the running sum of the last N ||r||^2, recomputed
 *             exactly (fsum) whenever the ring wraps
 *   ewrms     a = lam a + (1 - lam) ||r||^2, J = sqrt(a)
 *   peak      J = max of the last N ||r|| (monotonic deque)
 *   narendra  J = alpha ||r|| + beta re, re = gamma re + ||r||
 *   chi2      J = max(S, 0), S the running sum of the last N ||W r||^2
 *   cusum     g+- = max(0, g+- +- delta z - delta^2/2), z = W r; J = max over both and components
 *   glr       J = max_j ||sum_{i=k-j..k} W r(i)||^2 / (2 (j+1)) over the last N samples
 * Thresholds: fixed (value), adaptive (J0 + a E_u(||u - u0||)), majorant
 * (J0 + E(b), b = sum_j m_j ||u(k-j)|| + t max_{i <= k-M} ||u(i)||).
 */
#include <math.h>
#include <string.h>

#include "fdi_internal.h"

static double pymax(double a, double b) { return b > a ? b : a; }  /* Python max(a, b) */

void fdi_evaluator_layout(fdi_evaluator *e, fdi_slots *s, int kind, long dim, long cap)
{
    e->kind = kind;
    e->dim = dim;
    e->cap = cap;
    e->value = fdi_slot_d(s, 1);
    e->acc = fdi_slot_d(s, 1);
    e->buf = e->buf2 = NULL;
    switch (kind) {
    case FDI_EV_RMS:
    case FDI_EV_CHI2:
        e->buf = fdi_slot_d(s, (size_t)cap);
        break;
    case FDI_EV_PEAK:
        e->buf = fdi_slot_d(s, (size_t)cap + 1);
        e->buf2 = fdi_slot_d(s, (size_t)cap + 1);
        break;
    case FDI_EV_CUSUM:
        e->buf = fdi_slot_d(s, (size_t)dim);
        e->buf2 = fdi_slot_d(s, (size_t)dim);
        break;
    case FDI_EV_GLR:
        e->buf = fdi_slot_d(s, (size_t)cap * (size_t)dim);
        break;
    default:
        break;
    }
    e->i = fdi_slot_i(s, 3);
}

void fdi_evaluator_reset(fdi_evaluator *e)
{
    *e->value = 0.0;
    *e->acc = 0.0;
    e->i[0] = e->i[1] = e->i[2] = 0;
    switch (e->kind) {
    case FDI_EV_RMS:
    case FDI_EV_CHI2:
        memset(e->buf, 0, (size_t)e->cap * sizeof(double));
        break;
    case FDI_EV_PEAK:
        memset(e->buf, 0, ((size_t)e->cap + 1) * sizeof(double));
        memset(e->buf2, 0, ((size_t)e->cap + 1) * sizeof(double));
        break;
    case FDI_EV_CUSUM:
        memset(e->buf, 0, (size_t)e->dim * sizeof(double));
        memset(e->buf2, 0, (size_t)e->dim * sizeof(double));
        break;
    case FDI_EV_GLR:
        memset(e->buf, 0, (size_t)e->cap * (size_t)e->dim * sizeof(double));
        break;
    default:
        break;
    }
}

/* Slots [from, to) of buf hold zeros (the unfilled part of a ring, docs/semantics.md S5). */
static int zeros(const double *buf, size_t from, size_t to)
{
    for (; from < to; from++)
        if (buf[from] != 0.0)
            return 0;
    return 1;
}

/* A ring (rms, chi2) or a history (glr) of window n: position, count and contents as a run
 * from the initial state leaves them (count = min(samples, n); position = count until full). */
static int ring_check(const fdi_evaluator *e, fdi_int n, size_t width)
{
    const fdi_int *i = e->i;
    if (!(n >= 1 && n <= e->cap && i[0] >= 0 && i[0] < n && i[1] >= 0 && i[1] <= n && i[2] == 0))
        return 0;
    if (i[1] < n && i[0] != i[1])
        return 0;
    return zeros(e->buf, (size_t)i[1] * width, (size_t)e->cap * width);
}

/* The peak evaluator's deque: sample indices (integers) increasing, the newest k - 1, none older
 * than the window; values decreasing, >= 0; J the oldest value. Bounds every later step's work. */
static int peak_check(const fdi_evaluator *e, fdi_int n)
{
    fdi_int head = e->i[0], len = e->i[1], k = e->i[2], j;
    long ring = (long)n + 1;
    double prev_idx = -1.0, prev_val = INFINITY;
    if (!(n >= 1 && n <= e->cap && head >= 0 && head < ring && len >= 0 && len <= n && k >= 0 &&
          k < FDI_EXACT_MAX && (len == 0) == (k == 0)))
        return 0;
    for (j = 0; j < len; j++) {
        double idx = e->buf[(head + j) % ring], val = e->buf2[(head + j) % ring];
        if (!(idx == floor(idx) && idx > prev_idx && idx >= (double)(k - n) && val >= 0.0 && val < prev_val))
            return 0;
        prev_idx = idx;
        prev_val = val;
    }
    if (len > 0 && (prev_idx != (double)(k - 1) || *e->value != e->buf2[head]))
        return 0;
    return len > 0 || *e->value == 0.0;
}

int fdi_evaluator_check(const fdi_evaluator *e, const fdi_eval_def *def)
{
    fdi_int n = def->window, *i = e->i;
    double v = *e->value, a = *e->acc;
    long j;
    switch (e->kind) {
    case FDI_EV_RMS:
        return ring_check(e, n, 1) && v == sqrt((0.0 > a ? 0.0 : a) / (double)n) &&
               fdi_nonnegative(e->buf, (size_t)i[1]);
    case FDI_EV_CHI2:
        return ring_check(e, n, 1) && v == (0.0 > a ? 0.0 : a) && fdi_nonnegative(e->buf, (size_t)i[1]);
    case FDI_EV_GLR:
        return ring_check(e, n, (size_t)e->dim) && v >= 0.0;
    case FDI_EV_PEAK:
        return peak_check(e, n);
    case FDI_EV_EWRMS:
        return i[0] == 0 && i[1] == 0 && i[2] == 0 && a >= 0.0 && v == sqrt(a);
    case FDI_EV_CUSUM: {
        double best = e->buf[0], bm = e->buf2[0];
        if (i[0] != 0 || i[1] != 0 || i[2] != 0 || a != 0.0 || !fdi_nonnegative(e->buf, (size_t)e->dim) ||
            !fdi_nonnegative(e->buf2, (size_t)e->dim))
            return 0;
        for (j = 1; j < e->dim; j++) {
            best = pymax(best, e->buf[j]);
            bm = pymax(bm, e->buf2[j]);
        }
        return v == pymax(best, bm);
    }
    case FDI_EV_NARENDRA:
        return i[0] == 0 && i[1] == 0 && i[2] == 0 && a >= 0.0 && v >= 0.0;
    default:   /* norm */
        return i[0] == 0 && i[1] == 0 && i[2] == 0 && a == 0.0 && v >= 0.0;
    }
}

int fdi_nonnegative(const double *x, size_t n)
{
    size_t j;
    for (j = 0; j < n; j++)
        if (!(x[j] >= 0.0))
            return 0;
    return 1;
}

int fdi_evaluator_finite(const fdi_evaluator *e)
{
    long j;
    if (!isfinite(*e->value) || !isfinite(*e->acc))
        return 0;
    if (e->kind == FDI_EV_CUSUM)
        for (j = 0; j < e->dim; j++)
            if (!isfinite(e->buf[j]) || !isfinite(e->buf2[j]))
                return 0;
    if (e->kind == FDI_EV_GLR && e->i[1] > 0) {   /* the whitened vector stored last */
        long n = e->cap, last = (long)((e->i[0] + n - 1) % n);
        for (j = 0; j < e->dim; j++)
            if (!isfinite(e->buf[(size_t)last * (size_t)e->dim + (size_t)j]))
                return 0;
    }
    return 1;
}

/* Ring push with the running sum recomputed exactly at every wrap (evaluation.py _Ring). */
static void ring_push(fdi_evaluator *e, long n, double x)
{
    fdi_int i = e->i[0];
    *e->acc += x - e->buf[i];
    e->buf[i] = x;
    i++;
    if (e->i[1] < i)
        e->i[1] = i;
    if (i == n) {
        i = 0;
        *e->acc = fdi_fsum(e->buf, n);
    }
    e->i[0] = i;
}

double fdi_evaluator_step_sq(fdi_evaluator *e, const fdi_eval_def *def, double sq)
{
    double v = 0.0, x;
    switch (e->kind) {
    case FDI_EV_RMS: {
        double s;
        ring_push(e, def->window, sq);
        s = *e->acc;
        v = sqrt((0.0 > s ? 0.0 : s) / (double)def->window);
        break;
    }
    case FDI_EV_NORM:
        v = sqrt(sq);
        break;
    case FDI_EV_EWRMS:
        *e->acc = def->lam * *e->acc + (1.0 - def->lam) * sq;
        v = sqrt(*e->acc);
        break;
    case FDI_EV_NARENDRA:
        x = sqrt(sq);
        v = def->alpha * x + def->beta * *e->acc;
        *e->acc = def->gamma * *e->acc + x;
        break;
    case FDI_EV_PEAK: {
        /* deque of (sample index, value), values decreasing: ring of n + 1 slots */
        long cap = def->window + 1;
        fdi_int head = e->i[0], len = e->i[1], k = e->i[2];
        x = sqrt(sq);
        while (len > 0 && e->buf2[(head + len - 1) % cap] <= x)
            len--;
        e->buf[(head + len) % cap] = (double)k;
        e->buf2[(head + len) % cap] = x;
        len++;
        while (len > 1 && e->buf[head] <= (double)(k - def->window)) {   /* the newest (k) always stays */
            head = (head + 1) % cap;
            len--;
        }
        e->i[0] = head;
        e->i[1] = len;
        e->i[2] = k + 1;
        v = e->buf2[head];
        break;
    }
    default:
        break;
    }
    *e->value = v;
    return v;
}

double fdi_evaluator_step(fdi_evaluator *e, const fdi_eval_def *def, const double *r, double *work)
{
    long dim = e->dim, j, q;
    double v = 0.0;
    if (e->kind != FDI_EV_CHI2 && e->kind != FDI_EV_CUSUM && e->kind != FDI_EV_GLR) {
        double sq = 0.0;
        for (j = 0; j < dim; j++)
            sq += r[j] * r[j];
        return fdi_evaluator_step_sq(e, def, sq);
    }
    if (e->kind == FDI_EV_CHI2) {
        double s = 0.0;
        fdi_matvec(def->W, dim, dim, r, work);
        for (j = 0; j < dim; j++)
            s += work[j] * work[j];
        ring_push(e, def->window, s);
        s = *e->acc;
        v = 0.0 > s ? 0.0 : s;
    } else if (e->kind == FDI_EV_CUSUM) {
        double d = def->delta, best;
        fdi_matvec(def->W, dim, dim, r, work);
        for (j = 0; j < dim; j++) {
            e->buf[j] = pymax(0.0, e->buf[j] + d * work[j] - 0.5 * d * d);
            e->buf2[j] = pymax(0.0, e->buf2[j] - d * work[j] - 0.5 * d * d);
        }
        best = e->buf[0];
        for (j = 1; j < dim; j++)
            best = pymax(best, e->buf[j]);
        {
            double bm = e->buf2[0];
            for (j = 1; j < dim; j++)
                bm = pymax(bm, e->buf2[j]);
            best = pymax(best, bm);
        }
        v = best;
    } else { /* glr: history ring of the last N whitened vectors, newest at head - 1 */
        long n = def->window;
        fdi_int head = e->i[0], count = e->i[1];
        double *acc = work + dim, best = 0.0;
        fdi_matvec(def->W, dim, dim, r, e->buf + (size_t)head * (size_t)dim);
        head = (head + 1) % n;
        if (count < n)
            count++;
        e->i[0] = head;
        e->i[1] = count;
        for (q = 0; q < dim; q++)
            acc[q] = 0.0;
        for (j = 0; j < count; j++) {
            const double *hv = e->buf + (size_t)((head - 1 - j + 2 * n) % n) * (size_t)dim;
            double s = 0.0;
            for (q = 0; q < dim; q++)
                acc[q] += hv[q];
            for (q = 0; q < dim; q++)
                s += acc[q] * acc[q];
            best = pymax(best, s / (2.0 * (double)(j + 1)));
        }
        v = best;
    }
    *e->value = v;
    return v;
}

/* ------------------------------------------------------------------ thresholds */
void fdi_threshold_layout(fdi_threshold *t, fdi_slots *s, const fdi_threshold_def *def, long cap)
{
    t->def = def;
    t->value = fdi_slot_d(s, 1);
    t->hist = t->old_max = NULL;
    t->pos = NULL;
    if (def->kind != FDI_TH_FIXED)
        fdi_evaluator_layout(&t->ev, s, def->ev.kind, 1, cap);
    if (def->kind == FDI_TH_MAJORANT) {
        t->hist = fdi_slot_d(s, (size_t)def->n_taps);
        t->old_max = fdi_slot_d(s, 1);
        t->pos = fdi_slot_i(s, 1);
    }
}

void fdi_threshold_reset(fdi_threshold *t)
{
    const fdi_threshold_def *def = t->def;
    *t->value = def->kind == FDI_TH_FIXED ? def->value : def->J0;
    if (def->kind != FDI_TH_FIXED)
        fdi_evaluator_reset(&t->ev);
    if (def->kind == FDI_TH_MAJORANT) {
        memset(t->hist, 0, (size_t)def->n_taps * sizeof(double));
        *t->old_max = 0.0;
        *t->pos = 0;
    }
}

int fdi_threshold_check(const fdi_threshold *t, const fdi_eval_def *ev)
{
    const fdi_threshold_def *def = t->def;
    if (def->kind == FDI_TH_FIXED)
        return *t->value == def->value;
    if (!fdi_evaluator_check(&t->ev, ev))
        return 0;
    if (def->kind == FDI_TH_ADAPTIVE)
        return *t->value == def->J0 + def->a * *t->ev.value;
    return *t->value == def->J0 + *t->ev.value && *t->pos >= 0 && *t->pos < def->n_taps &&
           fdi_nonnegative(t->hist, (size_t)def->n_taps) && *t->old_max >= 0.0;
}

int fdi_threshold_finite(const fdi_threshold *t)
{
    if (!isfinite(*t->value))
        return 0;
    if (t->def->kind == FDI_TH_FIXED)
        return 1;
    if (!fdi_evaluator_finite(&t->ev))
        return 0;
    return t->def->kind != FDI_TH_MAJORANT || isfinite(*t->old_max);
}

double fdi_threshold_step(fdi_threshold *t, const fdi_eval_def *ev, double unorm)
{
    const fdi_threshold_def *def = t->def;
    if (def->kind == FDI_TH_ADAPTIVE) {
        *t->value = def->J0 + def->a * fdi_evaluator_step_sq(&t->ev, ev, unorm * unorm);
    } else if (def->kind == FDI_TH_MAJORANT) {
        /* hist[j] = ||u(k-j)|| lives at ring slot (pos + j) mod M */
        long M = def->n_taps, j;
        fdi_int pos = *t->pos;
        double b = 0.0;
        *t->old_max = pymax(*t->old_max, t->hist[(pos + M - 1) % M]);
        pos = (pos + M - 1) % M;
        t->hist[pos] = unorm;
        *t->pos = pos;
        for (j = 0; j < M; j++)
            b += def->taps[j] * t->hist[(pos + j) % M];
        b = b + def->tail * *t->old_max;
        *t->value = def->J0 + fdi_evaluator_step_sq(&t->ev, ev, b * b);
    }
    return *t->value;
}
