/*
 * FMU-state fuzz of the native diagnostic FMU in a plain C host (test tool of fmu-fdi, issue 22):
 * every STRIDE-th single-bit flip of a serialized FMU state, each followed by bounded doSteps.
 *
 *   native_state_fuzz 2|3 UNZIPDIR INPUT.csv STEP N_FAULTS STRIDE RESEAL
 *
 * The host runs the rows of INPUT.csv (header: time, then the FMU's inputs in its order), saves
 * and serializes the FMU state at the middle row and records the outputs of the next K rows
 * (at most 20) as the reference. Then, for bit b = 0, STRIDE, 2 STRIDE, ... of the serialized
 * bytes, a child process (fork) flips bit b, deserializes, sets the state, reads the outputs and
 * steps the same K rows. RESEAL = 1 first recomputes the image's trailing FNV-1a 64 checksum (docs/native-fmu.md),
 * so that the flip reaches the runtime's own validation instead of the checksum.
 * Each try ends in one of:
 *   refused     deserialize or set returned Error (a clean error)
 *   step_error  a doStep returned Error (a clean error, after the state was accepted)
 *   same        accepted; every output (after the set and the K steps) equals the reference
 *   different   accepted; an output differs from the reference (silently wrong unless the flip
 *               was in a value a host may legitimately set: inputs, time, threshold_scale)
 *   invalid     accepted; an output out of its type's range (a Real not finite, a Boolean not
 *               0/1, isolated_fault outside -1..N_FAULTS)
 *   hang        the child did not finish within 5 s (SIGALRM)
 *   crash       the child died of another signal
 * Prints one line: "tries=... refused=... step_error=... same=... different=... invalid=...
 * hang=... crash=...". Exit status 0 unless the host itself failed (1 usage/IO, 2 FMI call).
 * Compile: cc -std=c99 -I<fmpy/c-code> native_state_fuzz.c -ldl -lm
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

static void note(int status, const char *category, const char *message) {
    (void)status;
    (void)category;
    (void)message;  /* a million refusals would flood the output: the status says enough */
}

#include "fmu_face.h"

#define MAX_K 20
enum { R_SAME = 0, R_DIFFERENT = 1, R_REFUSED = 10, R_STEP_ERROR = 12, R_INVALID = 20 };

static uint64_t fnv1a64(const unsigned char *p, size_t n) {
    uint64_t h = 1469598103934665603ULL;
    size_t i;
    for (i = 0; i < n; i++) {
        h ^= p[i];
        h *= 1099511628211ULL;
    }
    return h;
}

/* The outputs right after the state was set (row 0 of got), then after each of the rows
 * [k0, k0 + K) of data (rows 1..K); got is (K + 1) x n_out. Returns a R_* code. */
static int run_rows(Fmu *f, void *c, const unsigned *in_vr, int n_in, const Var *const *outs, int n_out,
                    const double *data, int k0, int K, double h, int n_faults, double *got) {
    int k, i, st;
    for (k = -1; k < K; k++) {
        if (k >= 0) {
            if (set_reals(f, c, in_vr, (size_t)n_in, &data[(size_t)(k0 + k) * (size_t)n_in]) != 0)
                return R_STEP_ERROR;
            st = do_step(f, c, (k0 + k) * h, h);
            if (st >= 3) return R_STEP_ERROR;
        }
        for (i = 0; i < n_out; i++) {
            double v;
            const Var *o = outs[i];
            if (get_value(f, c, o, &v) != 0) return R_STEP_ERROR;
            if ((o->kind == K_REAL && !isfinite(v)) || (o->kind == K_BOOL && v != 0.0 && v != 1.0) ||
                (o->kind == K_INT && (v < -1.0 || v > n_faults)))
                return R_INVALID;
            got[(size_t)(k + 1) * (size_t)n_out + (size_t)i] = v;
        }
    }
    return R_SAME;
}

int main(int argc, char **argv) {
    Fmu fmu, *f = &fmu;
    Var vars[512];
    const Var *outs[512];
    unsigned in_vr[256];
    int nvars, i, k, n_in = 0, n_out = 0, rows = 0, K, k0, n_faults, reseal;
    long stride, bit, nbits;
    long tally[8] = {0}, tries = 0;
    double h, *data, *ref, *got;
    void *c, *state = NULL;
    size_t size = 0;
    unsigned char *img;
    if (argc != 8) {
        fprintf(stderr, "usage: native_state_fuzz 2|3 UNZIPDIR INPUT.csv STEP N_FAULTS STRIDE RESEAL\n");
        return 1;
    }
    h = atof(argv[4]);
    n_faults = atoi(argv[5]);
    stride = atol(argv[6]);
    reseal = atoi(argv[7]);
    if (stride < 1) return 1;
    if ((nvars = fmu_open(f, atoi(argv[1]) == 3, argv[2], vars, 512)) < 0) return nvars == -1 ? 1 : 2;
    for (i = 0; i < nvars; i++) {
        if (vars[i].input && n_in < 256) in_vr[n_in++] = vars[i].vr;
        if (vars[i].output) outs[n_out++] = &vars[i];
    }
    if (!(data = read_rows(argv[3], n_in, &rows))) return 1;
    k0 = rows / 2;
    K = rows - k0 < MAX_K ? rows - k0 : MAX_K;
    ref = calloc((size_t)(K + 1) * (size_t)n_out, sizeof(double));
    got = calloc((size_t)(K + 1) * (size_t)n_out, sizeof(double));
    c = instantiate(f, "fuzz", f->token);
    if (!c || init(f, c) != 0) return 2;
    for (k = 0; k < k0; k++) {
        if (set_reals(f, c, in_vr, (size_t)n_in, &data[(size_t)k * (size_t)n_in]) != 0) return 2;
        if (do_step(f, c, k * h, h) >= 3) return 2;
    }
    if (get_state(f, c, &state) != 0 || state_size(f, c, state, &size) != 0) return 2;
    img = malloc(size);
    if (serialize(f, c, state, img, size) != 0 || set_state(f, c, state) != 0) return 2;
    if (run_rows(f, c, in_vr, n_in, outs, n_out, data, k0, K, h, n_faults, ref) != R_SAME) return 2;
    nbits = (long)size * 8;
    fflush(stdout);
    for (bit = 0; bit < nbits; bit += stride) {
        pid_t pid = fork();
        int status;
        if (pid < 0) return 2;
        if (pid == 0) {
            void *s2 = NULL;
            int r;
            alarm(5);
            img[bit / 8] ^= (unsigned char)(1u << (bit % 8));
            if (reseal && size >= 8) {
                uint64_t sum = fnv1a64(img, size - 8);
                memcpy(img + size - 8, &sum, 8);
            }
            if (deserialize(f, c, img, size, &s2) != 0 || set_state(f, c, s2) != 0) _exit(R_REFUSED);
            r = run_rows(f, c, in_vr, n_in, outs, n_out, data, k0, K, h, n_faults, got);
            if (r == R_SAME && memcmp(got, ref, sizeof(double) * (size_t)(K + 1) * (size_t)n_out) != 0) r = R_DIFFERENT;
            _exit(r);
        }
        if (waitpid(pid, &status, 0) != pid) return 2;
        tries++;
        if (WIFSIGNALED(status)) tally[WTERMSIG(status) == SIGALRM ? 6 : 7]++;
        else if (WEXITSTATUS(status) == R_REFUSED) tally[0]++;
        else if (WEXITSTATUS(status) == R_STEP_ERROR) tally[1]++;
        else if (WEXITSTATUS(status) == R_SAME) tally[2]++;
        else if (WEXITSTATUS(status) == R_DIFFERENT) tally[3]++;
        else if (WEXITSTATUS(status) == R_INVALID) tally[4]++;
        else tally[7]++;
    }
    printf("bytes=%lu tries=%ld refused=%ld step_error=%ld same=%ld different=%ld invalid=%ld hang=%ld crash=%ld\n",
           (unsigned long)size, tries, tally[0], tally[1], tally[2], tally[3], tally[4], tally[6], tally[7]);
    free_state(f, c, &state);
    free_instance(f, c);
    free(img);
    free(data);
    free(ref);
    free(got);
    return 0;
}
