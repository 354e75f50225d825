/* fdi_decision.c - alarms, persistence, latching and fault isolation, per sample.
 *
 * The rules of fmu_fdi/runtime/decision.py (Frank 1990, sec. 7): the raw test of group i is
 * J_i >= J_th,i; its alarm rises when at least k of the last n raw tests fired (a ring of n
 * tests per group, oldest first), and stays up once latched. isolated_fault: 0 without an
 * alarm; with structure isolation the 1-based index of the only fault column of S equal to
 * the alarm pattern (-1 for none or several); with direction isolation the fault whose
 * direction makes the smallest angle with the residual, if the gap to the second smallest
 * angle is at least min_margin (-1 otherwise or for a zero residual); -1 with isolation none.
 */
#include <math.h>
#include <string.h>

#include "fdi_internal.h"

static void isolate(fdi_decision *dec, const double *r);
static int fdi_isolation_valid(fdi_decision *dec, int any);

void fdi_decision_layout(fdi_decision *dec, fdi_slots *s, fdi_carver *c, const fdi_design *d)
{
    size_t ng = (size_t)d->n_groups;
    dec->d = d;
    dec->raw = fdi_slot_b(s, ng * (size_t)d->n_of);
    dec->alarms = fdi_slot_b(s, ng);
    dec->latched = fdi_slot_b(s, ng);
    dec->pos = fdi_slot_i(s, ng);
    dec->isolated = fdi_slot_i(s, 1);
    dec->count = fdi_carve(c, ng * sizeof(fdi_int));
}

void fdi_decision_reset(fdi_decision *dec)
{
    size_t ng = (size_t)dec->d->n_groups;
    memset(dec->raw, 0, ng * (size_t)dec->d->n_of);
    memset(dec->alarms, 0, ng);
    memset(dec->latched, 0, ng);
    memset(dec->pos, 0, ng * sizeof(fdi_int));
    memset(dec->count, 0, ng * sizeof(fdi_int));
    *dec->isolated = 0;
}

/* Validate a loaded image and rebuild the counts: rings of 0/1 tests, alarms as persistence and
 * latch make them from the rings, isolated_fault as the isolation makes it from the alarms. */
int fdi_decision_load(fdi_decision *dec)
{
    const fdi_design *d = dec->d;
    long g, j, n = d->n_of;
    int any = 0;
    for (g = 0; g < d->n_groups; g++) {
        fdi_int cnt = 0;
        int up;
        if (dec->pos[g] < 0 || dec->pos[g] >= n || dec->alarms[g] > 1 || dec->latched[g] > 1)
            return 0;
        for (j = 0; j < n; j++) {
            unsigned char b = dec->raw[(size_t)g * (size_t)n + (size_t)j];
            if (b > 1)
                return 0;
            cnt += b;
        }
        dec->count[g] = cnt;
        up = cnt >= d->k_of;
        if (d->latch ? (dec->alarms[g] != dec->latched[g] || (up && !dec->latched[g]))
                     : (dec->latched[g] != 0 || dec->alarms[g] != up))
            return 0;
        any |= dec->alarms[g];
    }
    return fdi_isolation_valid(dec, any);
}

/* isolated_fault fits the alarms: 0 without an alarm; with one, what structure isolation gives
 * for the pattern, a fault with a direction or -1 (direction: the residual decided), -1 (none). */
static int fdi_isolation_valid(fdi_decision *dec, int any)
{
    const fdi_design *d = dec->d;
    fdi_int iso = *dec->isolated;
    if (!any)
        return iso == 0;
    if (d->isolation == FDI_ISO_STRUCTURE) {
        isolate(dec, NULL);
        return *dec->isolated == iso;
    }
    if (d->isolation == FDI_ISO_DIRECTION)
        return iso == -1 || (iso >= 1 && iso <= d->n_faults && d->Dvalid[iso - 1]);
    return iso == -1;
}

static void isolate(fdi_decision *dec, const double *r)
{
    const fdi_design *d = dec->d;
    long g, f, nf = d->n_faults, ng = d->n_groups;
    int any = 0;
    for (g = 0; g < ng; g++)
        any |= dec->alarms[g];
    if (!any) {
        *dec->isolated = 0;
        return;
    }
    if (d->isolation == FDI_ISO_STRUCTURE) {
        long matches = 0, which = -1;
        for (f = 0; f < nf; f++) {
            int same = 1;
            for (g = 0; g < ng && same; g++)
                same = (d->S[(size_t)g * (size_t)nf + (size_t)f] != 0) == (dec->alarms[g] != 0);
            if (same) {
                matches++;
                if (which < 0)
                    which = f;
            }
        }
        *dec->isolated = matches == 1 ? which + 1 : -1;
    } else if (d->isolation == FDI_ISO_DIRECTION) {
        long nr = d->n_r, i, best = -1;
        double nrm = 0.0, a_best = INFINITY, a_second = INFINITY, margin;
        if (!r) {   /* an overflowed sub-sample: the residual direction is unknown */
            *dec->isolated = -1;
            return;
        }
        for (i = 0; i < nr; i++)
            nrm += r[i] * r[i];
        nrm = sqrt(nrm);
        if (nrm == 0.0) {
            *dec->isolated = -1;
            return;
        }
        for (f = 0; f < nf; f++) {
            double c = 0.0, angle;
            if (!d->Dvalid[f])
                continue;
            for (i = 0; i < nr; i++)
                c += d->Ddir[(size_t)i * (size_t)nf + (size_t)f] * r[i];
            c = fabs(c) / nrm;
            c = c < 0.0 ? 0.0 : (c > 1.0 ? 1.0 : c);
            angle = acos(c);
            if (angle < a_best) {   /* stable order: the first of equal angles wins */
                a_second = a_best;
                a_best = angle;
                best = f;
            } else if (angle < a_second) {
                a_second = angle;
            }
        }
        margin = (isfinite(a_second) ? a_second : 3.141592653589793 / 2.0) - a_best;
        *dec->isolated = margin >= d->min_margin ? best + 1 : -1;
    } else {
        *dec->isolated = -1;
    }
}

void fdi_decision_step_fired(fdi_decision *dec, const unsigned char *fired, const double *r)
{
    const fdi_design *d = dec->d;
    long g, n = d->n_of;
    for (g = 0; g < d->n_groups; g++) {
        unsigned char *ring = dec->raw + (size_t)g * (size_t)n;
        unsigned char f = fired[g] != 0;
        fdi_int p = dec->pos[g];
        int up;
        dec->count[g] += (fdi_int)f - (fdi_int)ring[p];
        ring[p] = f;
        dec->pos[g] = (p + 1) % n;
        up = dec->count[g] >= d->k_of;
        if (d->latch) {
            dec->latched[g] = (unsigned char)(dec->latched[g] || up);
            up = dec->latched[g];
        }
        dec->alarms[g] = (unsigned char)up;
    }
    isolate(dec, r);
}

void fdi_decision_step(fdi_decision *dec, const double *evals, const double *thrs, const double *r,
                       unsigned char *fired)
{
    long g;
    for (g = 0; g < dec->d->n_groups; g++)
        fired[g] = evals[g] >= thrs[g];
    fdi_decision_step_fired(dec, fired, r);
}
