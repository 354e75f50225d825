/*
 * FMU-state fuzz of the native diagnostic FMU in a plain C host (test tool of fmu-fdi, issues 22 and 20):
 * every STRIDE-th mutation of a serialized FMU state, each accepted one followed by bounded doSteps.
 *
 *   native_state_fuzz 2|3 UNZIPDIR INPUT.csv STEP N_FAULTS STRIDE RESEAL [MODE]
 *
 * The host runs the rows of INPUT.csv (header: time, then the FMU's inputs in its order), saves
 * and serializes the FMU state at the middle row and records the outputs of the next K rows
 * (at most 20) as the reference. MODE (default bits) says what is tried, for m = 0, STRIDE, 2 STRIDE, ...:
 *   bits   flip bit m of the image;
 *   bytes  set byte m/3 of the image to 0x00, 0xFF or 0x80 (m mod 3; not a try where the byte
 *          holds that value): several bits at once, a double's sign and exponent at their
 *          extremes, a count to zero or huge;
 *   sizes  the image cut to m bytes (m < its size) or extended by m - size + 1 zero bytes (up to 8).
 * RESEAL = 1 first recomputes the (new) image's trailing FNV-1a 64 checksum (docs/native-fmu.md),
 * so that the mutation reaches the runtime's own validation instead of the checksum.
 * Deserializing and setting the mutated state run in this process (bounded by alarm(5); a crash or
 * a hang there ends the host with status 3 or 4 naming the try). A state they refuse costs no
 * process; every 16th refusal a child process steps the instance as it is, which must give the
 * reference outputs: a refused state leaves the instance as it was. A state they accept is stepped
 * in a child process (fork), so a crash or a hang is counted, not fatal, and the parent then sets
 * the saved state again. Each try ends in one of:
 *   refused     deserialize or set returned Error (a clean error)
 *   step_error  a doStep returned Error (a clean error, after the state was accepted)
 *   same        accepted; every output (after the set and the K steps) equals the reference
 *   different   accepted; an output differs from the reference (silently wrong unless the mutation
 *               was in a value a host may legitimately set: inputs, time, threshold_scale)
 *   invalid     accepted; an output out of its type's range (a Real not finite, a Boolean not
 *               0/1, isolated_fault outside -1..N_FAULTS)
 *   hang        the child did not finish within 5 s (SIGALRM)
 *   crash       the child died of another signal
 * and the refusal checks in: intact_checks (how many), changed_by_refusal (a refused state that
 * changed the instance: must be 0).
 * Prints one line: "bytes=... tries=... refused=... step_error=... same=... different=... invalid=...
 * hang=... crash=... intact_checks=... changed_by_refusal=...". Exit status 0 unless the host itself
 * failed (1 usage/IO, 2 FMI call, 3 a crash and 4 a hang in deserialize/set, in this process).
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
#define EXTRA 8 /* bytes a "sizes" try may add */
static const unsigned char BYTE_VALUES[3] = {0x00, 0xFF, 0x80}; /* what a "bytes" try writes */
enum { R_SAME = 0, R_DIFFERENT = 1, R_REFUSED = 10, R_STEP_ERROR = 12, R_INVALID = 20 };

static uint64_t fnv1a64(const unsigned char *p, size_t n);

/* the try in progress in this process, for the message of a crash or hang in deserialize/set */
static volatile sig_atomic_t current_try = -1;

static void in_process_signal(int sig) {
    char msg[96] = "native_state_fuzz: deserialize/set crashed or hung at try ";
    char digits[24];
    size_t n = strlen(msg), k = 0;
    long t = (long)current_try;
    do {
        digits[k++] = (char)('0' + t % 10);
        t /= 10;
    } while (t > 0 && k < sizeof digits);
    while (k > 0 && n + 2 < sizeof msg) msg[n++] = digits[--k];
    msg[n++] = '\n';
    if (write(2, msg, n) < 0) { /* nothing more to do in a signal handler */ }
    _exit(sig == SIGALRM ? 4 : 3);
}

static void on_signals(void (*handler)(int)) {
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = handler;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGSEGV, &sa, NULL);
    sigaction(SIGBUS, &sa, NULL);
    sigaction(SIGFPE, &sa, NULL);
    sigaction(SIGILL, &sa, NULL);
    sigaction(SIGABRT, &sa, NULL);
    sigaction(SIGALRM, &sa, NULL);
}

/* The mutated image of try m into buf (MODE, see above); returns its length. */
static size_t mutate(const unsigned char *img, size_t size, char mode, long m, int reseal, unsigned char *buf) {
    size_t len = size;
    memcpy(buf, img, size);
    if (mode == 'b') {
        buf[m / 8] ^= (unsigned char)(1u << (m % 8));
    } else if (mode == 'y') {
        buf[m / 3] = BYTE_VALUES[m % 3];
    } else {
        len = (size_t)m < size ? (size_t)m : (size_t)m + 1; /* cut to m bytes, or m - size + 1 added */
        if (len > size) memset(buf + size, 0, len - size);
    }
    if (reseal && len >= 8) {
        uint64_t sum = fnv1a64(buf, len - 8);
        memcpy(buf + len - 8, &sum, 8);
    }
    return len;
}

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

/* Step the instance as it is in a child process: R_* of its rows against the reference, or R_REFUSED + 100
 * + the signal that ended the child (a hang is SIGALRM). */
static int child_rows(Fmu *f, void *c, const unsigned *in_vr, int n_in, const Var *const *outs, int n_out,
                      const double *data, int k0, int K, double h, int n_faults, const double *ref, double *got) {
    int status;
    pid_t pid = fork();
    if (pid < 0) return -1;
    if (pid == 0) {
        int r;
        on_signals(SIG_DFL); /* a crash or hang here is the child's, counted by the parent */
        alarm(5);
        r = run_rows(f, c, in_vr, n_in, outs, n_out, data, k0, K, h, n_faults, got);
        if (r == R_SAME && memcmp(got, ref, sizeof(double) * (size_t)(K + 1) * (size_t)n_out) != 0) r = R_DIFFERENT;
        _exit(r);
    }
    if (waitpid(pid, &status, 0) != pid) return -1;
    return WIFSIGNALED(status) ? R_REFUSED + 100 + WTERMSIG(status) : WEXITSTATUS(status);
}

int main(int argc, char **argv) {
    Fmu fmu, *f = &fmu;
    Var vars[512];
    const Var *outs[512];
    unsigned in_vr[256];
    int nvars, i, k, n_in = 0, n_out = 0, rows = 0, K, k0, n_faults, reseal;
    long stride, m, tries_max, refusals = 0;
    long tally[8] = {0}, tries = 0, intact_checks = 0, changed_by_refusal = 0;
    double h, *data, *ref, *got;
    void *c, *state = NULL;
    size_t size = 0;
    unsigned char *img, *buf;
    char mode;
    if (argc != 8 && argc != 9) {
        fprintf(stderr, "usage: native_state_fuzz 2|3 UNZIPDIR INPUT.csv STEP N_FAULTS STRIDE RESEAL [bits|bytes|sizes]\n");
        return 1;
    }
    h = atof(argv[4]);
    n_faults = atoi(argv[5]);
    stride = atol(argv[6]);
    reseal = atoi(argv[7]);
    mode = argc == 9 ? (strcmp(argv[8], "bytes") == 0 ? 'y' : strcmp(argv[8], "sizes") == 0 ? 's'
                                                              : strcmp(argv[8], "bits") == 0 ? 'b' : 0) : 'b';
    if (stride < 1 || !mode) return 1;
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
    buf = malloc(size + EXTRA);
    if (!img || !buf || serialize(f, c, state, img, size) != 0 || set_state(f, c, state) != 0) return 2;
    if (run_rows(f, c, in_vr, n_in, outs, n_out, data, k0, K, h, n_faults, ref) != R_SAME) return 2;
    if (set_state(f, c, state) != 0) return 2; /* the instance at the saved state again */
    tries_max = mode == 'b' ? (long)size * 8 : mode == 'y' ? (long)size * 3 : (long)size + EXTRA;
    fflush(stdout);
    on_signals(in_process_signal);
    for (m = 0; m < tries_max; m += stride) {
        void *s2 = NULL;
        size_t len = mutate(img, size, mode, m, reseal, buf);
        int accepted, r;
        if (mode == 'y' && img[m / 3] == BYTE_VALUES[m % 3]) continue; /* the byte holds that value: no change */
        current_try = (sig_atomic_t)m;
        alarm(5);
        accepted = deserialize(f, c, buf, len, &s2) == 0 && set_state(f, c, s2) == 0;
        alarm(0);
        if (s2) free_state(f, c, &s2);
        tries++;
        if (!accepted) {
            tally[0]++;
            if (refusals++ % 16 == 0) { /* the refused state left the instance at the saved state */
                r = child_rows(f, c, in_vr, n_in, outs, n_out, data, k0, K, h, n_faults, ref, got);
                if (r < 0) return 2;
                intact_checks++;
                if (r != R_SAME) changed_by_refusal++;
            }
            continue;
        }
        r = child_rows(f, c, in_vr, n_in, outs, n_out, data, k0, K, h, n_faults, ref, got);
        if (r < 0) return 2;
        if (r >= R_REFUSED + 100) tally[r - R_REFUSED - 100 == SIGALRM ? 6 : 7]++;
        else if (r == R_STEP_ERROR) tally[1]++;
        else if (r == R_SAME) tally[2]++;
        else if (r == R_DIFFERENT) tally[3]++;
        else if (r == R_INVALID) tally[4]++;
        else tally[7]++;
        alarm(5);
        if (set_state(f, c, state) != 0) return 2; /* back to the saved state for the next try */
        alarm(0);
    }
    printf("bytes=%lu tries=%ld refused=%ld step_error=%ld same=%ld different=%ld invalid=%ld hang=%ld crash=%ld "
           "intact_checks=%ld changed_by_refusal=%ld\n",
           (unsigned long)size, tries, tally[0], tally[1], tally[2], tally[3], tally[4], tally[6], tally[7],
           intact_checks, changed_by_refusal);
    free_state(f, c, &state);
    free_instance(f, c);
    free(img);
    free(buf);
    free(data);
    free(ref);
    free(got);
    return 0;
}
