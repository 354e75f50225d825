/* fdi_rls.c - residuals of recursive least-squares parameter estimation, per sample.
 *
 * The rules of fmu_fdi/runtime/rls.py (Ljung 1999, sec. 11.2; Isermann & Muenchhof 2011),
 * operation by operation. Per estimator: the prefilter x+ = A x + B w, [psi; phi] = C x + D w
 * with w = v[inputs]; after `skip` samples the update
 *   eps = psi - phi' theta, s = mu + phi' P phi, K = P phi / s, theta += K eps,
 *   P = [(I - K phi') P (I - K phi')' + mu K K'] / mu, symmetrised, trace-bounded, reset
 *   by policy; sigma_e^2 tracked from min(eps^2 mu / s, c^2 sigma^2);
 * and from `warmup` samples on r_i = (theta_i - theta0_i) / (sqrt(P_ii) sigma),
 * sigma^2 = max(sigma_e^2, sigma_floor^2, (rho psi_rms)^2).
 */
#include <math.h>
#include <string.h>

#include "fdi_internal.h"

static double pymax(double a, double b) { return b > a ? b : a; }

void fdi_rls_layout(fdi_rls *g, fdi_slots *s, fdi_carver *c, const fdi_design *d)
{
    long e, ne = d->rls_n_est, maxp = 0, maxx = 0, maxin = 0;
    g->d = d;
    g->k = fdi_slot_i(s, 1);
    g->x = fdi_carve(c, (size_t)ne * sizeof(double *));
    g->theta = fdi_carve(c, (size_t)ne * sizeof(double *));
    g->P = fdi_carve(c, (size_t)ne * sizeof(double *));
    g->sigma2 = fdi_carve(c, (size_t)ne * sizeof(double *));
    g->psi2 = fdi_carve(c, (size_t)ne * sizeof(double *));
    g->updates = fdi_carve(c, (size_t)ne * sizeof(fdi_int *));
    g->resets = fdi_carve(c, (size_t)ne * sizeof(fdi_int *));
    for (e = 0; e < ne; e++) {
        const fdi_rls_est_def *est = &d->rls_est[e];
        double *px = fdi_slot_d(s, (size_t)est->nx), *pt = fdi_slot_d(s, (size_t)est->npar),
               *pP = fdi_slot_d(s, (size_t)(est->npar * est->npar)), *ps = fdi_slot_d(s, 1),
               *pq = fdi_slot_d(s, 1);
        fdi_int *pu = fdi_slot_i(s, 1), *pr = fdi_slot_i(s, 1);
        if (c->base) {
            g->x[e] = px;
            g->theta[e] = pt;
            g->P[e] = pP;
            g->sigma2[e] = ps;
            g->psi2[e] = pq;
            g->updates[e] = pu;
            g->resets[e] = pr;
        }
        if (est->npar > maxp)
            maxp = est->npar;
        if (est->nx > maxx)
            maxx = est->nx;
        if (est->n_in > maxin)
            maxin = est->n_in;
    }
    g->work = fdi_carve(c, (size_t)(3 * (maxp + 1) + maxin + 2 * maxx + 2 * maxp + 3 * maxp * maxp) * sizeof(double));
}

void fdi_rls_reset(fdi_rls *g)
{
    const fdi_design *d = g->d;
    long e, i;
    *g->k = 0;
    for (e = 0; e < d->rls_n_est; e++) {
        const fdi_rls_est_def *est = &d->rls_est[e];
        memset(g->x[e], 0, (size_t)est->nx * sizeof(double));
        memcpy(g->theta[e], est->theta0, (size_t)est->npar * sizeof(double));
        memset(g->P[e], 0, (size_t)(est->npar * est->npar) * sizeof(double));
        for (i = 0; i < est->npar; i++)
            g->P[e][i * est->npar + i] = d->rls_P0;
        *g->sigma2[e] = *g->psi2[e] = 0.0;
        *g->updates[e] = *g->resets[e] = 0;
    }
}

/* A state image as a run from the initial state leaves it: every sample from `skip` on updates
 * (updates = max(0, k - skip)), resets as the policy makes them, P exactly symmetric (it is
 * symmetrised every update), the noise estimates >= 0. */
int fdi_rls_check(const fdi_rls *g)
{
    const fdi_design *d = g->d;
    long e, i, j;
    fdi_int k = *g->k;
    if (k < 0 || k >= FDI_EXACT_MAX)
        return 0;
    for (e = 0; e < d->rls_n_est; e++) {
        const fdi_rls_est_def *est = &d->rls_est[e];
        fdi_int n = *g->updates[e], r = *g->resets[e];
        const double *P = g->P[e];
        long np = est->npar;
        if (n != (k > est->skip ? k - est->skip : 0) || r < 0 || r > n)
            return 0;
        if ((d->rls_policy == FDI_RLS_RESET_PERIODIC && r != n / d->rls_period) ||
            (d->rls_policy != FDI_RLS_RESET_PERIODIC && d->rls_policy != FDI_RLS_RESET_FLOOR && r != 0))
            return 0;
        if (!(*g->sigma2[e] >= 0.0 && *g->psi2[e] >= 0.0))
            return 0;
        for (i = 0; i < np; i++)
            for (j = 0; j < i; j++)
                if (P[i * np + j] != P[j * np + i])
                    return 0;
    }
    return 1;
}

int fdi_rls_finite(const fdi_rls *g)
{
    const fdi_design *d = g->d;
    long e, i;
    for (e = 0; e < d->rls_n_est; e++) {
        const fdi_rls_est_def *est = &d->rls_est[e];
        for (i = 0; i < est->nx; i++)
            if (!isfinite(g->x[e][i]))
                return 0;
        for (i = 0; i < est->npar; i++)
            if (!isfinite(g->theta[e][i]))
                return 0;
        for (i = 0; i < est->npar * est->npar; i++)
            if (!isfinite(g->P[e][i]))
                return 0;
        if (!isfinite(*g->sigma2[e]) || !isfinite(*g->psi2[e]))
            return 0;
    }
    return 1;
}

static double sigma_of(const fdi_rls *g, long e)
{
    const fdi_design *d = g->d;
    double f = d->rls_est[e].sigma_floor, m = *g->sigma2[e];
    m = pymax(m, f * f);
    m = pymax(m, d->rls_sigma_rel * d->rls_sigma_rel * *g->psi2[e]);
    return sqrt(m);
}

static void update(fdi_rls *g, long e, double psi, const double *phi, double *work)
{
    const fdi_design *d = g->d;
    const fdi_rls_est_def *est = &d->rls_est[e];
    long np = est->npar, i, j, q;
    double mu = d->rls_mu, *P = g->P[e], *theta = g->theta[e];
    double *Pphi = work, *K = Pphi + np, *J = K + np, *JP = J + np * np, *Pn = JP + np * np;
    double s = 0.0, err = 0.0, tr, gamma, e2;
    fdi_int n;
    fdi_matvec(P, np, np, phi, Pphi);
    for (i = 0; i < np; i++)
        s += phi[i] * Pphi[i];
    s = mu + s;
    for (i = 0; i < np; i++)
        K[i] = Pphi[i] / s;
    for (i = 0; i < np; i++)
        err += phi[i] * theta[i];
    err = psi - err;
    for (i = 0; i < np; i++)
        theta[i] = theta[i] + K[i] * err;
    for (i = 0; i < np; i++)
        for (j = 0; j < np; j++)
            J[i * np + j] = (i == j ? 1.0 : 0.0) - K[i] * phi[j];
    for (i = 0; i < np; i++)          /* JP = J P */
        for (j = 0; j < np; j++) {
            double acc = 0.0;
            for (q = 0; q < np; q++)
                acc += J[i * np + q] * P[q * np + j];
            JP[i * np + j] = acc;
        }
    for (i = 0; i < np; i++)          /* Pn = (JP J' + mu K K') / mu */
        for (j = 0; j < np; j++) {
            double acc = 0.0;
            for (q = 0; q < np; q++)
                acc += JP[i * np + q] * J[j * np + q];
            Pn[i * np + j] = (acc + mu * (K[i] * K[j])) / mu;
        }
    for (i = 0; i < np; i++)
        for (j = 0; j < np; j++)
            P[i * np + j] = 0.5 * (Pn[i * np + j] + Pn[j * np + i]);
    tr = 0.0;
    for (i = 0; i < np; i++)
        tr += P[i * np + i];
    if (tr > est->trace_max) {
        double f = est->trace_max / tr;
        for (i = 0; i < np * np; i++)
            P[i] = P[i] * f;
    }
    n = *g->updates[e] = *g->updates[e] + 1;
    {
        int reset = 0;
        if (d->rls_policy == FDI_RLS_RESET_FLOOR) {
            tr = 0.0;
            for (i = 0; i < np; i++)
                tr += P[i * np + i];
            reset = tr < est->trace_min;
        } else if (d->rls_policy == FDI_RLS_RESET_PERIODIC) {
            reset = n % d->rls_period == 0;
        }
        if (reset) {
            for (i = 0; i < np; i++)
                for (j = 0; j < np; j++)
                    P[i * np + j] = i == j ? d->rls_P0 : 0.0;
            *g->resets[e] += 1;
        }
    }
    gamma = pymax(1.0 / (double)n, 1.0 - d->rls_mu_sigma);
    e2 = err * err * mu / s;
    if (d->rls_clip != 0.0 && !d->rls_clip_after_inf && n > d->rls_clip_after) {
        double sg = sigma_of(g, e), c = d->rls_clip * d->rls_clip * (sg * sg);
        e2 = c < e2 ? c : e2;
    }
    *g->sigma2[e] += gamma * (e2 - *g->sigma2[e]);
    *g->psi2[e] += gamma * (psi * psi - *g->psi2[e]);
}

void fdi_rls_step(fdi_rls *g, const double *v, double *r)
{
    const fdi_design *d = g->d;
    long e, i, off = 0;
    fdi_int k = *g->k;
    for (e = 0; e < d->rls_n_est; e++) {
        const fdi_rls_est_def *est = &d->rls_est[e];
        long np = est->npar, nz = np + 1, nx = est->nx;
        double *z = g->work, *cx = z + nz, *dw = cx + nz, *w = dw + nz, *xn = w + est->n_in, *bw = xn + nx,
               *upd = bw + nx, *x = g->x[e];
        for (i = 0; i < est->n_in; i++)
            w[i] = v[est->inputs[i]];
        fdi_matvec(est->C, nz, nx, x, cx);
        fdi_matvec(est->D, nz, est->n_in, w, dw);
        for (i = 0; i < nz; i++)
            z[i] = cx[i] + dw[i];
        fdi_matvec(est->A, nx, nx, x, xn);
        fdi_matvec(est->B, nx, est->n_in, w, bw);
        for (i = 0; i < nx; i++)
            x[i] = xn[i] + bw[i];
        if (k < est->skip) {
            for (i = 0; i < np; i++)
                r[off + i] = 0.0;
        } else {
            update(g, e, z[0], z + 1, upd);
            if (k + 1 < est->warmup) {
                for (i = 0; i < np; i++)
                    r[off + i] = 0.0;
            } else {
                double sg = sigma_of(g, e);
                for (i = 0; i < np; i++) {
                    double den = sqrt(g->P[e][i * np + i]) * sg;
                    r[off + i] = den > 0.0 ? (g->theta[e][i] - est->theta0[i]) / den : 0.0;
                }
            }
        }
        off += np;
    }
    *g->k = k + 1;
}
