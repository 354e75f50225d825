/* native_runtime_driver.c - a plain C host of the native runtime (no FMI, no Python), run
 * under AddressSanitizer/UBSan or valgrind by tests/test_native_runtime_memory.py.
 *
 * Two instances of the design (compiled in as design_data.c) are driven side by side with the
 * same pseudo-random calls: inputs with NaN/Inf bursts and 1e300 glitches, steps of Ts,
 * multiples, odd and refused sizes, threshold_scale changes, resets and state roll-backs.
 * Instance B is also handed hostile state images (truncated, wrong magic, another size,
 * flipped bytes, a NaN, out-of-range indices) and must refuse every one with its state
 * unchanged: A and B must then produce bit-identical outputs throughout. Usage:
 * driver N_CALLS SEED; exit status 0 when every check held.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fdi_runtime.h"

typedef struct { unsigned long long s; } rng_t;

static double uniform(rng_t *r)
{
    r->s = r->s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(r->s >> 11) / 9007199254740992.0;
}

static double gauss(rng_t *r)
{
    double a = uniform(r), b = uniform(r);
    return sqrt(-2.0 * log(a + 1e-300)) * cos(6.283185307179586 * b);
}

static int fail(const char *what, long k)
{
    fprintf(stderr, "FAIL at call %ld: %s\n", k, what);
    return 1;
}

int main(int argc, char **argv)
{
    const fdi_design *d = &FDI_DESIGN;
    long n_calls = argc > 1 ? atol(argv[1]) : 2000, k;
    rng_t rng = {argc > 2 ? (unsigned long long)atoll(argv[2]) : 1ULL};
    size_t nu = fdi_n_u(d), ny = fdi_n_y(d), no = fdi_n_outputs(d), size = fdi_runtime_size(d), i;
    double Ts = fdi_sample_time(d), h = Ts;
    const double steps[] = {1.0, 1.0, 3.0, 0.37, 2.5, 1.0 / 40.0, 20001.0};
    fdi_runtime *a = malloc(size), *b = malloc(size);
    double *u = malloc((nu + 1) * sizeof(double)), *y = malloc((ny + 1) * sizeof(double));
    unsigned char *saved = NULL, *bad = NULL;
    size_t ssize = 0;
    char why[256];
    long discards = 0, refused = 0, restores = 0;
    if (!a || !b || !u || !y)
        return 2;
    if (fdi_runtime_init(a, d, size - 1) != FDI_ERROR)   /* too small a block is refused */
        return fail("init accepted a block one byte too small", -1);
    if (fdi_runtime_init(a, d, size) != FDI_OK || fdi_runtime_init(b, d, size) != FDI_OK)
        return fail("init", -1);
    for (k = 0; k < n_calls; k++) {
        fdi_status sa, sb;
        double r = uniform(&rng);
        for (i = 0; i < nu; i++)
            u[i] = gauss(&rng);
        for (i = 0; i < ny; i++)
            y[i] = gauss(&rng);
        if (r < 0.02 && ny)
            y[0] = NAN;
        else if (r < 0.03 && ny)
            y[ny - 1] = 1e300;
        else if (r < 0.035 && nu)
            u[0] = -INFINITY;
        if (uniform(&rng) < 0.03) {
            double cand = Ts * steps[(int)(uniform(&rng) * 7.0)];
            sa = fdi_runtime_advance(a, u, y, cand, why, sizeof why);
            sb = fdi_runtime_advance(b, u, y, cand, why, sizeof why);
            if (sa == FDI_OK)
                h = cand;
            else
                discards++;
        } else {
            sa = fdi_runtime_advance(a, u, y, h, why, sizeof why);
            sb = fdi_runtime_advance(b, u, y, h, why, sizeof why);
        }
        if (sa != sb || sa == FDI_ERROR)
            return fail("advance status", k);
        if (memcmp(fdi_runtime_outputs(a), fdi_runtime_outputs(b), no * sizeof(double)) != 0)
            return fail("outputs of the two instances differ", k);
        for (i = 0; i < no; i++)
            if (!isfinite(fdi_runtime_outputs(a)[i]))
                return fail("a non-finite output", k);
        r = uniform(&rng);
        if (r < 0.02) {                        /* save */
            free(saved);
            free(bad);
            ssize = fdi_runtime_state_size(a);
            saved = malloc(ssize);
            bad = malloc(ssize);
            if (!saved || !bad)
                return 2;
            fdi_runtime_get_state(a, saved);
        } else if (r < 0.04 && saved) {        /* roll back both, attack B first */
            size_t j, off;
            memcpy(bad, saved, ssize);
            bad[0] ^= 0xFF;                                                     /* magic */
            if (fdi_runtime_set_state(b, bad, ssize, why, sizeof why) != FDI_ERROR)
                return fail("a state with a wrong magic was accepted", k);
            if (fdi_runtime_set_state(b, saved, ssize - 1, why, sizeof why) != FDI_ERROR ||
                fdi_runtime_set_state(b, saved, 10, why, sizeof why) != FDI_ERROR)
                return fail("a truncated state was accepted", k);
            memcpy(bad, saved, ssize);
            bad[8] ^= 0x01;                                                     /* design hash */
            if (fdi_runtime_set_state(b, bad, ssize, why, sizeof why) != FDI_ERROR)
                return fail("a state of another design was accepted", k);
            memcpy(bad, saved, ssize);
            for (j = 48; j + sizeof(double) <= ssize; j += sizeof(double) * 7) { /* NaNs (the first in the doubles) */
                double nan = NAN;
                memcpy(bad + j, &nan, sizeof nan);
            }
            if (fdi_runtime_set_state(b, bad, ssize, why, sizeof why) != FDI_ERROR)
                return fail("a state holding NaN was accepted", k);
            refused += 5;
            {   /* every refusal left B exactly as A */
                size_t na = fdi_runtime_state_size(a);
                unsigned char *ia = malloc(na), *ib = malloc(na);
                if (!ia || !ib || fdi_runtime_state_size(b) != na)
                    return 2;
                fdi_runtime_get_state(a, ia);
                fdi_runtime_get_state(b, ib);
                if (memcmp(ia, ib, na) != 0)
                    return fail("a refused state image changed the instance", k);
                free(ia);
                free(ib);
            }
            memcpy(bad, saved, ssize);
            for (off = 48; off < ssize; off++)                                /* garbage everywhere */
                bad[off] = (unsigned char)(off % 3 == 0 ? 0x7F : bad[off]);
            (void)fdi_runtime_set_state(b, bad, ssize, why, sizeof why);        /* must not crash */
            if (fdi_runtime_set_state(a, saved, ssize, why, sizeof why) != FDI_OK ||
                fdi_runtime_set_state(b, saved, ssize, why, sizeof why) != FDI_OK)
                return fail(why, k);
            restores++;
            h = -1.0;   /* the step size comes with the state: keep whatever it was */
        } else if (r < 0.045) {
            fdi_runtime_reset(a);
            fdi_runtime_reset(b);
            h = Ts;
        } else if (r < 0.05) {
            double s = uniform(&rng) * 3.0;
            if (fdi_runtime_set_threshold_scale(a, s, why, sizeof why) != FDI_OK ||
                fdi_runtime_set_threshold_scale(b, s, why, sizeof why) != FDI_OK)
                return fail("threshold scale", k);
            if (fdi_runtime_set_threshold_scale(a, NAN, why, sizeof why) != FDI_ERROR ||
                fdi_runtime_threshold_scale(a) != s)
                return fail("a NaN threshold scale was accepted", k);
        }
        if (h < 0.0)
            h = Ts;   /* a restored state may hold another step: the next call switches back to Ts */
    }
    printf("calls %ld, discarded steps %ld, restores %ld, hostile states refused %ld, block %lu bytes, state %lu bytes\n",
           n_calls, discards, restores, refused, (unsigned long)size, (unsigned long)ssize);
    free(saved);
    free(bad);
    free(a);
    free(b);
    free(u);
    free(y);
    return 0;
}
