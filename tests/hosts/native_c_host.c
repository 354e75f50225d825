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

#include "host_text.h"

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

enum { K_REAL, K_INT, K_BOOL };
typedef struct {
    char name[128];
    unsigned vr;
    int kind;
    int output;
    int input;
} Var;

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

static void logger2(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    char buf[1024];
    va_list ap;
    (void)env;
    (void)instance;
    va_start(ap, message);
    vsnprintf(buf, sizeof buf, message, ap);
    va_end(ap);
    note((int)status, category, buf);
}

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    note((int)status, category, message);
}

/* variables of an FMI 2.0 (<ScalarVariable> + type child) or FMI 3.0 (<Float64 ...>) description */
static int parse(const char *xml, int v3, Var *vars, int max, char *ident, char *token) {
    const char *p = strstr(xml, "<ModelVariables"), *end = strstr(xml, "</ModelVariables>");
    const char *cs = strstr(xml, "<CoSimulation");
    int n = 0;
    char buf[128];
    if (!p || !end || !cs) return -1;
    if (!attr(cs, "modelIdentifier", ident, 256) || !strstr(xml, "<fmiModelDescription") ||
        !attr(strstr(xml, "<fmiModelDescription"), v3 ? "instantiationToken" : "guid", token, 256))
        return -1;
    while ((p = strchr(p + 1, '<')) && p < end && n < max) {
        const char *tag = p + 1, *body;
        Var *v = &vars[n];
        if (*tag == '/' || *tag == '!') continue;
        if (!v3 && strncmp(tag, "ScalarVariable", 14) != 0) continue;
        if (v3 && !(strncmp(tag, "Float64", 7) == 0 || strncmp(tag, "Int32", 5) == 0 ||
                    strncmp(tag, "Boolean", 7) == 0))
            continue;
        memset(v, 0, sizeof *v);
        attr(p, "name", v->name, sizeof v->name);
        attr(p, "valueReference", buf, sizeof buf);
        v->vr = (unsigned)strtoul(buf, NULL, 10);
        if (attr(p, "causality", buf, sizeof buf)) {
            v->output = strcmp(buf, "output") == 0;
            v->input = strcmp(buf, "input") == 0;
        }
        body = v3 ? tag : strchr(p, '>') + 1;
        if (!v3) {
            while (*body == ' ' || *body == '\n' || *body == '\r' || *body == '\t') body++;
            body++;
        }
        v->kind = (strncmp(body, "Float64", 7) == 0 || strncmp(body, "Real", 4) == 0) ? K_REAL
                  : (strncmp(body, "Int32", 5) == 0 || strncmp(body, "Integer", 7) == 0) ? K_INT
                                                                                             : K_BOOL;
        n++;
    }
    return n;
}

/* ---- a uniform face over the two FMI versions --------------------------------------------- */
typedef struct {
    int v3;
    void *lib;
    char ident[256], token[256], resources[4096];
    /* FMI 2 */
    fmi2InstantiateTYPE *i2;
    fmi2FreeInstanceTYPE *free2;
    fmi2SetupExperimentTYPE *setup2;
    fmi2EnterInitializationModeTYPE *enter2;
    fmi2ExitInitializationModeTYPE *exit2;
    fmi2TerminateTYPE *term2;
    fmi2ResetTYPE *reset2;
    fmi2GetRealTYPE *gr2;
    fmi2GetIntegerTYPE *gi2;
    fmi2GetBooleanTYPE *gb2;
    fmi2SetRealTYPE *sr2;
    fmi2SetIntegerTYPE *si2;
    fmi2DoStepTYPE *step2;
    fmi2GetFMUstateTYPE *gs2;
    fmi2SetFMUstateTYPE *ss2;
    fmi2FreeFMUstateTYPE *fs2;
    fmi2SerializedFMUstateSizeTYPE *sz2;
    fmi2SerializeFMUstateTYPE *ser2;
    fmi2DeSerializeFMUstateTYPE *de2;
    fmi2CallbackFunctions cb;
    /* FMI 3 */
    fmi3InstantiateCoSimulationTYPE *i3;
    fmi3FreeInstanceTYPE *free3;
    fmi3EnterInitializationModeTYPE *enter3;
    fmi3ExitInitializationModeTYPE *exit3;
    fmi3TerminateTYPE *term3;
    fmi3ResetTYPE *reset3;
    fmi3GetFloat64TYPE *gr3;
    fmi3GetInt32TYPE *gi3;
    fmi3GetBooleanTYPE *gb3;
    fmi3SetFloat64TYPE *sr3;
    fmi3SetInt32TYPE *si3;
    fmi3DoStepTYPE *step3;
    fmi3GetFMUStateTYPE *gs3;
    fmi3SetFMUStateTYPE *ss3;
    fmi3FreeFMUStateTYPE *fs3;
    fmi3SerializedFMUStateSizeTYPE *sz3;
    fmi3SerializeFMUStateTYPE *ser3;
    fmi3DeserializeFMUStateTYPE *de3;
} Fmu;

static void *sym(Fmu *f, const char *name) {
    void *p = dlsym(f->lib, name);
    if (!p) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return p;
}

#define LOAD(field, name) *(void **)(&f->field) = sym(f, name)

static void load(Fmu *f) {
    if (!f->v3) {
        LOAD(i2, "fmi2Instantiate"); LOAD(free2, "fmi2FreeInstance"); LOAD(setup2, "fmi2SetupExperiment");
        LOAD(enter2, "fmi2EnterInitializationMode"); LOAD(exit2, "fmi2ExitInitializationMode");
        LOAD(term2, "fmi2Terminate"); LOAD(reset2, "fmi2Reset"); LOAD(gr2, "fmi2GetReal");
        LOAD(gi2, "fmi2GetInteger"); LOAD(gb2, "fmi2GetBoolean"); LOAD(sr2, "fmi2SetReal");
        LOAD(si2, "fmi2SetInteger"); LOAD(step2, "fmi2DoStep"); LOAD(gs2, "fmi2GetFMUstate");
        LOAD(ss2, "fmi2SetFMUstate"); LOAD(fs2, "fmi2FreeFMUstate"); LOAD(sz2, "fmi2SerializedFMUstateSize");
        LOAD(ser2, "fmi2SerializeFMUstate"); LOAD(de2, "fmi2DeSerializeFMUstate");
        f->cb.logger = logger2;
        f->cb.allocateMemory = calloc;
        f->cb.freeMemory = free;
    } else {
        LOAD(i3, "fmi3InstantiateCoSimulation"); LOAD(free3, "fmi3FreeInstance");
        LOAD(enter3, "fmi3EnterInitializationMode"); LOAD(exit3, "fmi3ExitInitializationMode");
        LOAD(term3, "fmi3Terminate"); LOAD(reset3, "fmi3Reset"); LOAD(gr3, "fmi3GetFloat64");
        LOAD(gi3, "fmi3GetInt32"); LOAD(gb3, "fmi3GetBoolean"); LOAD(sr3, "fmi3SetFloat64");
        LOAD(si3, "fmi3SetInt32"); LOAD(step3, "fmi3DoStep"); LOAD(gs3, "fmi3GetFMUState");
        LOAD(ss3, "fmi3SetFMUState"); LOAD(fs3, "fmi3FreeFMUState"); LOAD(sz3, "fmi3SerializedFMUStateSize");
        LOAD(ser3, "fmi3SerializeFMUState"); LOAD(de3, "fmi3DeserializeFMUState");
    }
}

static void *instantiate(Fmu *f, const char *name, const char *token) {
    if (!f->v3) return f->i2(name, fmi2CoSimulation, token, f->resources, &f->cb, fmi2False, fmi2True);
    return f->i3(name, token, f->resources, fmi3False, fmi3True, fmi3False, fmi3False, NULL, 0, NULL, logger3, NULL);
}

static int init(Fmu *f, void *c) {
    if (!f->v3) {
        if (f->setup2(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK) return 3;
        if (f->enter2(c) != fmi2OK) return 3;
        return f->exit2(c);
    }
    if (f->enter3(c, fmi3False, 0.0, 0.0, fmi3False, 0.0) != fmi3OK) return 3;
    return f->exit3(c);
}

static int do_step(Fmu *f, void *c, double t, double h) {
    fmi3Boolean ev, term, early;
    fmi3Float64 last;
    if (!f->v3) return f->step2(c, t, h, fmi2True);
    return f->step3(c, t, h, fmi3True, &ev, &term, &early, &last);
}

static int set_reals(Fmu *f, void *c, const unsigned *vr, size_t n, const double *v) {
    return f->v3 ? (int)f->sr3(c, vr, n, v, n) : (int)f->sr2(c, vr, n, v);
}

static int get_value(Fmu *f, void *c, const Var *v, double *out) {
    int s;
    if (v->kind == K_REAL) {
        double x;
        s = f->v3 ? (int)f->gr3(c, &v->vr, 1, &x, 1) : (int)f->gr2(c, &v->vr, 1, &x);
        *out = x;
    } else if (v->kind == K_INT) {
        int x;
        s = f->v3 ? (int)f->gi3(c, &v->vr, 1, &x, 1) : (int)f->gi2(c, &v->vr, 1, &x);
        *out = x;
    } else if (f->v3) {
        fmi3Boolean x;
        s = (int)f->gb3(c, &v->vr, 1, &x, 1);
        *out = x ? 1.0 : 0.0;
    } else {
        fmi2Boolean x;
        s = (int)f->gb2(c, &v->vr, 1, &x);
        *out = x ? 1.0 : 0.0;
    }
    return s;
}

static void free_instance(Fmu *f, void *c) {
    if (f->v3) f->free3(c);
    else f->free2(c);
}

static int reset(Fmu *f, void *c) { return f->v3 ? (int)f->reset3(c) : (int)f->reset2(c); }

static int get_state(Fmu *f, void *c, void **s) { return f->v3 ? (int)f->gs3(c, s) : (int)f->gs2(c, s); }
static int set_state(Fmu *f, void *c, void *s) { return f->v3 ? (int)f->ss3(c, s) : (int)f->ss2(c, s); }
static int free_state(Fmu *f, void *c, void **s) { return f->v3 ? (int)f->fs3(c, s) : (int)f->fs2(c, s); }
static int state_size(Fmu *f, void *c, void *s, size_t *n) {
    return f->v3 ? (int)f->sz3(c, s, n) : (int)f->sz2(c, s, n);
}
static int serialize(Fmu *f, void *c, void *s, unsigned char *buf, size_t n) {
    return f->v3 ? (int)f->ser3(c, s, buf, n) : (int)f->ser2(c, s, (fmi2Byte *)buf, n);
}
static int deserialize(Fmu *f, void *c, const unsigned char *buf, size_t n, void **s) {
    return f->v3 ? (int)f->de3(c, buf, n, s) : (int)f->de2(c, (const fmi2Byte *)buf, n, s);
}

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
    char path[8192], *xml, *csv, *line, *save = NULL;
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
    memset(f, 0, sizeof *f);
    f->v3 = atoi(argv[1]) == 3;
    h = atof(argv[5]);
    snprintf(path, sizeof path, "%s/modelDescription.xml", argv[2]);
    if (!(xml = read_file(path))) return 1;
    nvars = parse(xml, f->v3, vars, 512, f->ident, f->token);
    free(xml);
    if (nvars <= 0) return 1;
    for (i = 0; i < nvars; i++) {
        if (vars[i].input) in_vr[n_in++] = vars[i].vr;
        if (vars[i].output) outs[n_out++] = &vars[i];
    }
    snprintf(path, sizeof path, "%s/binaries/%s/%s.so", argv[2], f->v3 ? "x86_64-linux" : "linux64", f->ident);
    f->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!f->lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    snprintf(f->resources, sizeof f->resources, f->v3 ? "%s/resources/" : "file://%s/resources", argv[2]);
    load(f);
    misuse(f, vars, nvars, h);

    if (!(csv = read_file(argv[3]))) return 1;
    for (line = csv; *line; line++) rows += *line == '\n';
    rows -= 1;  /* header */
    table = calloc((size_t)rows * (size_t)n_out + 1, sizeof(double));
    replay = calloc((size_t)rows * (size_t)n_out + 1, sizeof(double));
    data = calloc((size_t)rows * (size_t)n_in + 1, sizeof(double));
    line = strtok_r(csv, "\n", &save);  /* header: time, then the inputs in the FMU's order */
    for (k = 0; k < rows && (line = strtok_r(NULL, "\n", &save)); k++) {
        char *tok, *s2 = NULL;
        tok = strtok_r(line, ",", &s2);  /* time */
        for (i = 0; i < n_in && (tok = strtok_r(NULL, ",", &s2)); i++) data[(size_t)k * (size_t)n_in + (size_t)i] = strtod(tok, NULL);
    }
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
    free(csv);
    return g_failed ? 3 : 0;
}
