/*
 * Plain C host for the native diagnostic FMU, FMI 2.0 or FMI 3.0 co-simulation (test tool of
 * fmu-fdi): no Python in the process, no LD_PRELOAD; meant to run under valgrind or ASan.
 *
 *   native_c_host 2|3 UNZIPDIR INPUT.csv OUTPUT.csv STEP
 *
 * 1. Misuse, on instances of their own, each check printed as "CHECK <name> ok|FAILED":
 *    calls out of order return Error with a logged reason and leave the instance in the Error
 *    state until Reset; setting an output, a wrong type, an unknown value reference, a bad
 *    threshold_scale and corrupt or truncated FMU states return Error and leave the instance
 *    usable; a step that is no multiple of Ts returns Discard with a reason and the next step
 *    is served as if it had not happened; a wrong GUID/token refuses instantiation.
 * 2. The run: for each row k of INPUT.csv (header: time, then the FMU's input names) set the
 *    inputs, doStep(k STEP, STEP), write every output (%.17g) to row k of OUTPUT.csv; FMU
 *    states are saved at the middle row, serialized, deserialized and restored at the end
 *    (checked: the rows after the restore equal the rows after the save); three more instances,
 *    each in a thread of its own, run the same rows at the same time and must agree bit for bit.
 * Exit status: 0 all fine, 1 usage/IO, 2 an FMI call failed, 3 a check failed.
 * Compile: cc -std=c99 -I<fmpy/c-code> native_c_host.c -ldl -lpthread
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <pthread.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>


static int g_failed = 0;
static int g_log_errors = 0;           /* Error messages seen since the last reset of the counter */
static char g_last_error[1024] = "";

static void check(int ok, const char *what) {
    printf("CHECK %s %s\n", what, ok ? "ok" : "FAILED");
    if (!ok) g_failed = 1;
}

static void note(int status, const char *category, const char *message) {
    printf("[%d][%s] %s\n", status, category ? category : "", message);
    if (status >= 3) {
        g_log_errors++;
        snprintf(g_last_error, sizeof g_last_error, "%s", message);
    }
}

#include "fmu_face.h"

static int error_logged(const char *needle) {
    int ok = g_log_errors > 0 && strstr(g_last_error, needle) != NULL;
    g_log_errors = 0;
    return ok;
}

/* ---- 1. misuse ------------------------------------------------------------------------------ */
static void misuse(Fmu *f, const Var *vars, int nvars, double h) {
    void *c, *s = NULL, *s2 = NULL;
    unsigned in_vr = 0, out_vr = 0, scale_vr = 0, bad_vr = 100000u;
    double x = 1.0, nan = NAN;
    int i, n_in = 0, k;
    size_t size = 0;
    unsigned char *buf;
    double before[64], after[64];
    const Var *outs[64];
    int n_out = 0;
    for (i = 0; i < nvars; i++) {
        if (vars[i].input && !n_in++) in_vr = vars[i].vr;
        if (vars[i].output && vars[i].kind == K_REAL && !out_vr) out_vr = vars[i].vr;
        if (vars[i].output && n_out < 64) outs[n_out++] = &vars[i];
        if (strcmp(vars[i].name, "threshold_scale") == 0) scale_vr = vars[i].vr;
    }

    check(instantiate(f, "wrong_token", "{00000000-0000-0000-0000-000000000000}") == NULL &&
              error_logged("does not match"), "wrong-token-refused");

    c = instantiate(f, "misuse", f->token);
    check(c != NULL, "instantiate");
    if (!c) return;
    check(do_step(f, c, 0.0, h) == 3 && error_logged("called in Instantiated"), "step-before-init-is-error");
    check(do_step(f, c, 0.0, h) == 3 && error_logged("an earlier call failed"), "error-state-sticks");
    check(reset(f, c) == 0 && init(f, c) == 0 && do_step(f, c, 0.0, h) == 0, "reset-heals");
    check(set_reals(f, c, &out_vr, 1, &x) == 3 && error_logged("is an output"), "set-output-is-error");
    check(reset(f, c) == 0 && init(f, c) == 0, "reset-again");
    check(set_reals(f, c, &bad_vr, 1, &x) == 3 && error_logged("no variable has value reference"), "unknown-vr");
    check(reset(f, c) == 0 && init(f, c) == 0, "reset-3");
    {
        int one = 1;
        check((f->v3 ? (int)f->si3(c, &in_vr, 1, &one, 1) : (int)f->si2(c, &in_vr, 1, &one)) == 3 &&
                  error_logged("is a Real variable"), "wrong-type");
    }
    check(reset(f, c) == 0 && init(f, c) == 0, "reset-4");
    /* bad values: Error, refused, instance still usable (no reset needed) */
    check(set_reals(f, c, &scale_vr, 1, &nan) == 3 && error_logged("threshold_scale"), "scale-nan-refused");
    check(do_step(f, c, 0.0, h) == 0, "usable-after-refused-scale");
    /* a step that is no multiple of Ts: Discard, reason, instance unchanged */
    for (k = 0; k < n_out; k++) get_value(f, c, outs[k], &before[k]);
    check(get_state(f, c, &s) == 0, "get-state");
    check(do_step(f, c, h, 0.37 * h) == 2, "odd-step-discarded");
    for (k = 0; k < n_out; k++) get_value(f, c, outs[k], &after[k]);
    check(memcmp(before, after, sizeof(double) * (size_t)n_out) == 0, "discard-changes-nothing");
    check(do_step(f, c, h, h) == 0, "step-after-discard");
    /* FMU states: serialize, corrupt, truncate */
    check(state_size(f, c, s, &size) == 0 && size > 0, "state-size");
    buf = malloc(size);
    check(serialize(f, c, s, buf, size) == 0, "serialize");
    check(deserialize(f, c, buf, size - 1, &s2) == 3 && error_logged("does not fit") && s2 == NULL, "truncated-refused");
    buf[0] ^= 0xFF;
    check(deserialize(f, c, buf, size, &s2) == 3 && error_logged("bad magic") && s2 == NULL, "corrupt-refused");
    buf[0] ^= 0xFF;
    buf[size - 1] ^= 0x5A;  /* inside the runtime image: the runtime's validation decides */
    if (deserialize(f, c, buf, size, &s2) == 0) {
        int st = set_state(f, c, s2);
        check(st == 0 || (st == 3 && error_logged("refused")), "tampered-state-validated");
        free_state(f, c, &s2);
    }
    buf[size - 1] ^= 0x5A;
    check(do_step(f, c, 2 * h, h) == 0, "usable-after-refused-state");
    check(deserialize(f, c, buf, size, &s2) == 0 && set_state(f, c, s2) == 0, "valid-state-restored");
    for (k = 0; k < n_out; k++) get_value(f, c, outs[k], &after[k]);
    check(memcmp(before, after, sizeof(double) * (size_t)n_out) == 0, "restored-outputs");
    free(buf);
    free_state(f, c, &s2);
    free_state(f, c, &s);
    check(free_state(f, c, &s) == 0, "free-null-state");
    check((f->v3 ? (int)f->term3(c) : (int)f->term2(c)) == 0, "terminate");
    check(do_step(f, c, 3 * h, h) == 3 && error_logged("called in Terminated"), "step-after-terminate");
    free_instance(f, c);
    if (f->v3) {  /* FMI 3.0 with eventModeUsed: Event Mode after initialisation, no events, then Step Mode */
        fmi3EnterEventModeTYPE *enter_event = (fmi3EnterEventModeTYPE *)(size_t)dlsym(f->lib, "fmi3EnterEventMode");
        fmi3EnterStepModeTYPE *enter_step = (fmi3EnterStepModeTYPE *)(size_t)dlsym(f->lib, "fmi3EnterStepMode");
        fmi3UpdateDiscreteStatesTYPE *update =
            (fmi3UpdateDiscreteStatesTYPE *)(size_t)dlsym(f->lib, "fmi3UpdateDiscreteStates");
        fmi3Boolean need = 1, term = 1, nom = 1, val = 1, next = 1;
        fmi3Float64 next_t;
        c = f->i3("events", f->token, f->resources, fmi3False, fmi3True, fmi3True, fmi3False, NULL, 0, NULL, logger3,
                  NULL);
        check(c && f->enter3(c, fmi3False, 0.0, 0.0, fmi3False, 0.0) == fmi3OK && f->exit3(c) == fmi3OK &&
                  do_step(f, c, 0.0, h) == 3 && error_logged("called in Event Mode"), "event-mode-first");
        check(f->reset3(c) == fmi3OK && f->enter3(c, fmi3False, 0.0, 0.0, fmi3False, 0.0) == fmi3OK &&
                  f->exit3(c) == fmi3OK && update(c, &need, &term, &nom, &val, &next, &next_t) == fmi3OK &&
                  !need && !term && !next && enter_step(c) == fmi3OK && do_step(f, c, 0.0, h) == 0 &&
                  enter_event(c) == fmi3OK && enter_step(c) == fmi3OK && do_step(f, c, h, h) == 0,
              "event-mode-cycle");
        if (c) f->free3(c);
    }
    (void)n_in;
}

/* ---- 2. the run ----------------------------------------------------------------------------- */
#define N_THREADS 3
typedef struct {
    Fmu *f;
    const double *data;
    int rows, n_in, n_out;
    const unsigned *in_vr;
    const Var *const *outs;
    double h;
    double *table;
    int status;
} Job;

static void *run_job(void *arg) {
    Job *j = arg;
    void *c = instantiate(j->f, "thread", j->f->token);
    int k, i;
    if (!c || init(j->f, c) != 0) {
        j->status = 2;
        return NULL;
    }
    for (k = 0; k < j->rows && !j->status; k++) {
        if (set_reals(j->f, c, j->in_vr, (size_t)j->n_in, &j->data[(size_t)k * (size_t)j->n_in]) != 0 ||
            do_step(j->f, c, k * j->h, j->h) != 0)
            j->status = 2;
        for (i = 0; i < j->n_out; i++)
            get_value(j->f, c, j->outs[i], &j->table[(size_t)k * (size_t)j->n_out + (size_t)i]);
    }
    free_instance(j->f, c);
    return NULL;
}
int main(int argc, char **argv) {
    Fmu fmu, *f = &fmu;
    Var vars[512];
    int nvars, i, k, n_in = 0, n_out = 0, rows = 0;
    unsigned in_vr[256];
    const Var *outs[256];
    double h, *table = NULL, *replay = NULL, *data = NULL;
    void *c, *state = NULL, *state2 = NULL;
    FILE *out;
    if (argc != 6) {
        fprintf(stderr, "usage: native_c_host 2|3 UNZIPDIR INPUT.csv OUTPUT.csv STEP\n");
        return 1;
    }
    h = atof(argv[5]);
    if ((nvars = fmu_open(f, atoi(argv[1]) == 3, argv[2], vars, 512)) < 0) return nvars == -1 ? 1 : 2;
    for (i = 0; i < nvars; i++) {
        if (vars[i].input) in_vr[n_in++] = vars[i].vr;
        if (vars[i].output) outs[n_out++] = &vars[i];
    }
    misuse(f, vars, nvars, h);

    if (!(data = read_rows(argv[3], n_in, &rows))) return 1;
    table = calloc((size_t)rows * (size_t)n_out + 1, sizeof(double));
    replay = calloc((size_t)rows * (size_t)n_out + 1, sizeof(double));
    c = instantiate(f, "run", f->token);
    if (!c || init(f, c) != 0) return 2;
    for (k = 0; k < rows; k++) {
        if (k == rows / 2 && get_state(f, c, &state) != 0) return 2;
        if (set_reals(f, c, in_vr, (size_t)n_in, &data[(size_t)k * (size_t)n_in]) != 0) return 2;
        if (do_step(f, c, k * h, h) != 0) return 2;
        for (i = 0; i < n_out; i++)
            if (get_value(f, c, outs[i], &table[(size_t)k * (size_t)n_out + (size_t)i]) != 0) return 2;
    }
    /* more instances of the same FMU at once, each in a thread of its own: the same rows */
    {
        Job jobs[N_THREADS];
        pthread_t tid[N_THREADS];
        int ok = 1;
        for (i = 0; i < N_THREADS; i++) {
            Job j = {f, data, rows, n_in, n_out, in_vr, outs, h, NULL, 0};
            j.table = calloc((size_t)rows * (size_t)n_out + 1, sizeof(double));
            jobs[i] = j;
            pthread_create(&tid[i], NULL, run_job, &jobs[i]);
        }
        for (i = 0; i < N_THREADS; i++) {
            pthread_join(tid[i], NULL);
            ok = ok && jobs[i].status == 0 &&
                 memcmp(jobs[i].table, table, sizeof(double) * (size_t)rows * (size_t)n_out) == 0;
            free(jobs[i].table);
        }
        check(ok, "instances-in-threads-agree");
    }
    /* the saved state, through serialize + deserialize, restored: the outputs of the saved row */
    {
        size_t size;
        unsigned char *buf;
        if (state_size(f, c, state, &size) != 0) return 2;
        buf = malloc(size);
        if (serialize(f, c, state, buf, size) != 0 || deserialize(f, c, buf, size, &state2) != 0 ||
            set_state(f, c, state2) != 0)
            return 2;
        free(buf);
        for (i = 0; i < n_out; i++) get_value(f, c, outs[i], &replay[i]);
        check(rows < 2 || memcmp(replay, &table[(size_t)(rows / 2 - 1) * (size_t)n_out],
                                 sizeof(double) * (size_t)n_out) == 0, "serialized-state-round-trip");
        free_state(f, c, &state2);
        free_state(f, c, &state);
    }
    if ((f->v3 ? (int)f->term3(c) : (int)f->term2(c)) != 0) return 2;
    free_instance(f, c);
    dlclose(f->lib);

    if (!(out = fopen(argv[4], "w"))) return 1;
    fprintf(out, "time");
    for (i = 0; i < n_out; i++) fprintf(out, ",%s", outs[i]->name);
    fprintf(out, "\n");
    for (k = 0; k < rows; k++) {
        fprintf(out, "%.17g", k * h);
        for (i = 0; i < n_out; i++) fprintf(out, ",%.17g", table[(size_t)k * (size_t)n_out + (size_t)i]);
        fprintf(out, "\n");
    }
    fclose(out);
    free(table);
    free(replay);
    free(data);
    return g_failed ? 3 : 0;
}
