/*
 * Minimal FMI 2.0 co-simulation host without Python in the process (test tool of fmu-fdi).
 *
 *   c_host UNZIPDIR INPUT.csv OUTPUT.csv STEP
 *
 * Loads UNZIPDIR/binaries/linux64/<modelIdentifier>.so with dlopen, instantiates it with the
 * resource URI file://UNZIPDIR/resources, and for each row k of INPUT.csv (header: time and
 * names of inputs or tunable parameters) sets the inputs, reads every output into row k of
 * OUTPUT.csv and calls fmi2DoStep(t0 + k*STEP, STEP). Reals are written with %.17g (exact).
 * The FMU's log goes to stdout. Exit status: 0 ok, 1 usage/IO, 2 FMI call failed.
 *
 * A pythonfmu FMU needs, in the environment: LD_PRELOAD=<libpython3.x.so> (its library leaves
 * the Py* symbols undefined), PYTHONHOME=<base prefix> and PYTHONPATH=<site-packages with
 * numpy>; see fmu_fdi.fmu.hosts.c_host_env.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "host_text.h"

/* FMI 2.0 types, written from the standard's definitions */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef const char *fmi2String;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef struct {
    void (*logger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

typedef fmi2Component (*InstantiateF)(fmi2String, fmi2Type, fmi2String, fmi2String, const fmi2CallbackFunctions *,
                                      fmi2Boolean, fmi2Boolean);
typedef fmi2Status (*SetupF)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
typedef fmi2Status (*ModeF)(fmi2Component);
typedef void (*FreeF)(fmi2Component);
typedef fmi2Status (*RealF)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *);
typedef fmi2Status (*IntF)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Integer *);
typedef fmi2Status (*SetRealF)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Real *);
typedef fmi2Status (*SetIntF)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Integer *);
typedef fmi2Status (*DoStepF)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);

enum { T_REAL, T_INTEGER, T_BOOLEAN, T_OTHER };
typedef struct {
    char name[256];
    fmi2ValueReference vr;
    int type;
    int output;
} Var;

static const char *STATUS[] = {"OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING"};

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    va_list args;
    (void)env;
    printf("[%s][%s][%s] ", STATUS[status < 6 ? status : 5], instance ? instance : "", category ? category : "");
    va_start(args, message);
    vprintf(message, args); /* FMI log messages are printf formats */
    va_end(args);
    printf("\n");
    fflush(stdout);
}

static int parse_variables(const char *xml, Var *vars, int max) {
    int n = 0;
    const char *p = xml;
    while ((p = strstr(p, "<ScalarVariable")) && n < max) {
        char buf[64] = "";
        Var *v = &vars[n];
        attr(p, "name", v->name, sizeof v->name);
        attr(p, "valueReference", buf, sizeof buf);
        v->vr = (fmi2ValueReference)strtoul(buf, NULL, 10);
        v->output = attr(p, "causality", buf, sizeof buf) && strcmp(buf, "output") == 0;
        const char *body = strchr(p, '>') + 1;
        while (*body == ' ' || *body == '\n' || *body == '\r' || *body == '\t') body++;
        v->type = strncmp(body, "<Real", 5) == 0      ? T_REAL
                  : strncmp(body, "<Integer", 8) == 0 ? T_INTEGER
                  : strncmp(body, "<Boolean", 8) == 0 ? T_BOOLEAN
                                                      : T_OTHER;
        n++;
        p = body;
    }
    return n;
}

static void *sym(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) { fprintf(stderr, "missing symbol %s\n", name); exit(2); }
    return f;
}

#define CHECK(call)                                                                  \
    do {                                                                             \
        fmi2Status s_ = (call);                                                      \
        if (s_ > fmi2Warning) {                                                      \
            fprintf(stderr, "%s returned %s\n", #call, STATUS[s_ < 6 ? s_ : 5]);     \
            return 2;                                                                \
        }                                                                            \
    } while (0)

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: %s UNZIPDIR INPUT.csv OUTPUT.csv STEP\n", argv[0]);
        return 1;
    }
    const char *dir = argv[1];
    double h = strtod(argv[4], NULL);
    char path[4096], ident[256], guid[256], uri[4200];
    snprintf(path, sizeof path, "%s/modelDescription.xml", dir);
    char *xml = read_file(path);
    if (!xml) { fprintf(stderr, "cannot read %s\n", path); return 1; }
    const char *root = strstr(xml, "<fmiModelDescription");
    const char *cs = strstr(xml, "<CoSimulation");
    if (!root || !cs || !attr(root, "guid", guid, sizeof guid) || !attr(cs, "modelIdentifier", ident, sizeof ident)) {
        fprintf(stderr, "no guid/CoSimulation modelIdentifier in %s\n", path);
        return 1;
    }
    static Var vars[4096];
    int nvars = parse_variables(xml, vars, 4096);

    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, ident);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "dlopen failed: %s\n", dlerror()); return 2; }
    InstantiateF instantiate = (InstantiateF)sym(lib, "fmi2Instantiate");
    SetupF setup = (SetupF)sym(lib, "fmi2SetupExperiment");
    ModeF enter = (ModeF)sym(lib, "fmi2EnterInitializationMode");
    ModeF leave = (ModeF)sym(lib, "fmi2ExitInitializationMode");
    ModeF terminate = (ModeF)sym(lib, "fmi2Terminate");
    FreeF free_instance = (FreeF)sym(lib, "fmi2FreeInstance");
    RealF get_real = (RealF)sym(lib, "fmi2GetReal");
    IntF get_integer = (IntF)sym(lib, "fmi2GetInteger");
    IntF get_boolean = (IntF)sym(lib, "fmi2GetBoolean");
    SetRealF set_real = (SetRealF)sym(lib, "fmi2SetReal");
    SetIntF set_integer = (SetIntF)sym(lib, "fmi2SetInteger");
    SetIntF set_boolean = (SetIntF)sym(lib, "fmi2SetBoolean");
    DoStepF do_step = (DoStepF)sym(lib, "fmi2DoStep");

    /* input CSV: header, then rows; columns other than time are matched to variables by name */
    FILE *in = fopen(argv[2], "r");
    FILE *out = fopen(argv[3], "w");
    if (!in || !out) { fprintf(stderr, "cannot open CSV files\n"); return 1; }
    static char line[65536];
    if (!fgets(line, sizeof line, in)) { fprintf(stderr, "empty input CSV\n"); return 1; }
    int col_var[512], ncols = 0;
    for (char *tok = strtok(line, ",\r\n"); tok && ncols < 512; tok = strtok(NULL, ",\r\n")) {
        while (*tok == '"') tok++;
        char *q = strchr(tok, '"');
        if (q) *q = 0;
        col_var[ncols] = -1;
        for (int i = 0; i < nvars; i++)
            if (strcmp(vars[i].name, tok) == 0) col_var[ncols] = i;
        if (ncols > 0 && col_var[ncols] < 0) { fprintf(stderr, "no variable %s\n", tok); return 1; }
        ncols++;
    }

    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    fmi2Component c = instantiate("c_host", fmi2CoSimulation, guid, uri, &cb, 0, 1);
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 2; }

    fprintf(out, "time");
    for (int i = 0; i < nvars; i++)
        if (vars[i].output) fprintf(out, ",%s", vars[i].name);
    fprintf(out, "\n");

    double t0 = 0.0;
    long k = 0;
    int initialized = 0;
    while (fgets(line, sizeof line, in)) {
        double vals[512];
        int n = 0;
        for (char *tok = strtok(line, ",\r\n"); tok && n < ncols; tok = strtok(NULL, ",\r\n")) vals[n++] = strtod(tok, NULL);
        if (n != ncols) { fprintf(stderr, "row %ld has %d of %d columns\n", k, n, ncols); return 1; }
        if (!initialized) {
            t0 = vals[0];
            CHECK(setup(c, 0, 0.0, t0, 0, 0.0));
            CHECK(enter(c));
        }
        for (int j = 1; j < ncols; j++) {
            Var *v = &vars[col_var[j]];
            if (v->type == T_REAL) CHECK(set_real(c, &v->vr, 1, &vals[j]));
            else {
                fmi2Integer iv = (fmi2Integer)vals[j];
                CHECK(v->type == T_INTEGER ? set_integer(c, &v->vr, 1, &iv) : set_boolean(c, &v->vr, 1, &iv));
            }
        }
        if (!initialized) {
            CHECK(leave(c));
            initialized = 1;
        }
        fprintf(out, "%.17g", t0 + (double)k * h);
        for (int i = 0; i < nvars; i++) {
            Var *v = &vars[i];
            if (!v->output) continue;
            if (v->type == T_REAL) {
                fmi2Real r;
                CHECK(get_real(c, &v->vr, 1, &r));
                fprintf(out, ",%.17g", r);
            } else if (v->type == T_INTEGER) {
                fmi2Integer iv;
                CHECK(get_integer(c, &v->vr, 1, &iv));
                fprintf(out, ",%d", iv);
            } else if (v->type == T_BOOLEAN) {
                fmi2Boolean b;
                CHECK(get_boolean(c, &v->vr, 1, &b));
                fprintf(out, ",%s", b ? "true" : "false");
            } else {
                fprintf(out, ",");
            }
        }
        fprintf(out, "\n");
        CHECK(do_step(c, t0 + (double)k * h, h, 1));
        k++;
    }
    fclose(in);
    fclose(out);
    CHECK(terminate(c));
    free_instance(c);
    /* pythonfmu 0.7 keeps its interpreter in a global std::shared_ptr whose C++ destructor
       runs among the exit handlers, *before* the library's own destructor assigns nullptr to
       it again: a use-after-free at process exit ("free(): corrupted unsorted chunks",
       depending on the heap layout). dlclose does not unload the library (pythonfmu's
       interpreter thread pins it). Calling its exported finalizePythonInterpreter() once all
       instances are freed finalises the interpreter now and leaves the global empty, so the
       exit-time destructors have nothing left to free. */
    {
        void (*finalize)(void) = (void (*)(void))dlsym(lib, "finalizePythonInterpreter");
        if (finalize) finalize();
    }
    dlclose(lib);
    free(xml);
    printf("c_host: %ld steps\n", k);
    return 0;
}
