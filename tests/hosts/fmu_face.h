/* fmu_face.h - one face over the FMI 2.0 and FMI 3.0 co-simulation API of the native diagnostic
 * FMU for the plain C test hosts (native_c_host.c, native_state_fuzz.c): the variable list from
 * modelDescription.xml, the functions by dlsym, and the calls both versions share. C99,
 * header-only (static functions). The host defines note(status, category, message), which
 * receives every logger message, before including this file. */
#ifndef FMU_FACE_H
#define FMU_FACE_H

#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "host_text.h"

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

static void note(int status, const char *category, const char *message);

enum { K_REAL, K_INT, K_BOOL };
typedef struct {
    char name[128];
    unsigned vr;
    int kind;
    int output;
    int input;
} Var;


static inline void logger2(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
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

static inline void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    note((int)status, category, message);
}


/* variables of an FMI 2.0 (<ScalarVariable> + type child) or FMI 3.0 (<Float64 ...>) description */
static inline int parse(const char *xml, int v3, Var *vars, int max, char *ident, char *token) {
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

static inline void load(Fmu *f) {
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

static inline int init(Fmu *f, void *c) {
    if (!f->v3) {
        if (f->setup2(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK) return 3;
        if (f->enter2(c) != fmi2OK) return 3;
        return f->exit2(c);
    }
    if (f->enter3(c, fmi3False, 0.0, 0.0, fmi3False, 0.0) != fmi3OK) return 3;
    return f->exit3(c);
}

static inline int do_step(Fmu *f, void *c, double t, double h) {
    fmi3Boolean ev, term, early;
    fmi3Float64 last;
    if (!f->v3) return f->step2(c, t, h, fmi2True);
    return f->step3(c, t, h, fmi3True, &ev, &term, &early, &last);
}

static inline int set_reals(Fmu *f, void *c, const unsigned *vr, size_t n, const double *v) {
    return f->v3 ? (int)f->sr3(c, vr, n, v, n) : (int)f->sr2(c, vr, n, v);
}

static inline int get_value(Fmu *f, void *c, const Var *v, double *out) {
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

static inline void free_instance(Fmu *f, void *c) {
    if (f->v3) f->free3(c);
    else f->free2(c);
}

static inline int reset(Fmu *f, void *c) { return f->v3 ? (int)f->reset3(c) : (int)f->reset2(c); }

static inline int get_state(Fmu *f, void *c, void **s) { return f->v3 ? (int)f->gs3(c, s) : (int)f->gs2(c, s); }
static inline int set_state(Fmu *f, void *c, void *s) { return f->v3 ? (int)f->ss3(c, s) : (int)f->ss2(c, s); }
static inline int free_state(Fmu *f, void *c, void **s) { return f->v3 ? (int)f->fs3(c, s) : (int)f->fs2(c, s); }
static inline int state_size(Fmu *f, void *c, void *s, size_t *n) {
    return f->v3 ? (int)f->sz3(c, s, n) : (int)f->sz2(c, s, n);
}
static inline int serialize(Fmu *f, void *c, void *s, unsigned char *buf, size_t n) {
    return f->v3 ? (int)f->ser3(c, s, buf, n) : (int)f->ser2(c, s, (fmi2Byte *)buf, n);
}
static inline int deserialize(Fmu *f, void *c, const unsigned char *buf, size_t n, void **s) {
    return f->v3 ? (int)f->de3(c, buf, n, s) : (int)f->de2(c, (const fmi2Byte *)buf, n, s);
}


/* Open the FMU unzipped in DIR (FMI 3.0 if v3): its variables into vars (at most max), the
 * library loaded. Returns the number of variables, -1 (unreadable description) or -2 (dlopen). */
static inline int fmu_open(Fmu *f, int v3, const char *dir, Var *vars, int max) {
    char path[8192], *xml;
    int nvars;
    memset(f, 0, sizeof *f);
    f->v3 = v3;
    snprintf(path, sizeof path, "%s/modelDescription.xml", dir);
    if (!(xml = read_file(path))) return -1;
    nvars = parse(xml, f->v3, vars, max, f->ident, f->token);
    free(xml);
    if (nvars <= 0) return -1;
    snprintf(path, sizeof path, "%s/binaries/%s/%s.so", dir, f->v3 ? "x86_64-linux" : "linux64", f->ident);
    if (!(f->lib = dlopen(path, RTLD_NOW | RTLD_LOCAL))) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return -2;
    }
    snprintf(f->resources, sizeof f->resources, f->v3 ? "%s/resources/" : "file://%s/resources", dir);
    load(f);
    return nvars;
}

/* The rows of a CSV file (header: time, then n_in input values per row) as a rows x n_in table
 * (free it); *rows = the number of rows. NULL if unreadable. */
static inline double *read_rows(const char *path, int n_in, int *rows) {
    char *csv = read_file(path), *line, *save = NULL;
    double *data;
    int k, i, n = 0;
    if (!csv) return NULL;
    for (line = csv; *line; line++) n += *line == '\n';
    n -= 1;  /* header */
    data = calloc((size_t)(n > 0 ? n : 0) * (size_t)n_in + 1, sizeof(double));
    line = strtok_r(csv, "\n", &save);
    for (k = 0; k < n && (line = strtok_r(NULL, "\n", &save)); k++) {
        char *tok, *s2 = NULL;
        tok = strtok_r(line, ",", &s2);  /* time */
        for (i = 0; i < n_in && (tok = strtok_r(NULL, ",", &s2)); i++)
            data[(size_t)k * (size_t)n_in + (size_t)i] = strtod(tok, NULL);
    }
    free(csv);
    *rows = n;
    return data;
}

#endif
