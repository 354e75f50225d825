/*
 * Minimal FMI 3.0 co-simulation host for the native plant FMUs (test tool; no Python in the process).
 *
 *   plant_fmi3_host UNZIPDIR MODEL_IDENTIFIER TOKEN STEPS H INPUT_VR K0 VALUE OUT_VRS
 *
 * Instantiates the FMU, initialises it, steps it STEPS times by H, setting the Float64 input
 * INPUT_VR to VALUE before step K0, and prints the Float64 outputs OUT_VRS (comma-separated value
 * references, at most 64) after every step as "k v1 v2 ..." (%.17g: exact). Also checks that misuse
 * is refused (a wrong token, an unknown value reference). Exit status 0 ok, 1 usage, 2 a call
 * failed, 3 a misuse was accepted.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi3FunctionTypes.h"

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    printf("LOG %d %s %s\n", (int)status, category, message);
}

int main(int argc, char **argv) {
    char path[4096];
    void *lib;
    fmi3Instance c;
    fmi3ValueReference in_vr, vr, out[64];
    fmi3Float64 y[64];
    size_t n_out = 0, i;
    char *text, *end;
    fmi3Float64 value, h, x;
    fmi3Boolean ev, term, early;
    fmi3Float64 last;
    long k, steps, k0;
    if (argc != 10) {
        fprintf(stderr, "usage: plant_fmi3_host UNZIPDIR ID TOKEN STEPS H INPUT_VR K0 VALUE OUT_VRS\n");
        return 1;
    }
    steps = atol(argv[4]);
    h = atof(argv[5]);
    in_vr = (fmi3ValueReference)atol(argv[6]);
    k0 = atol(argv[7]);
    value = atof(argv[8]);
    for (text = argv[9]; *text && n_out < 64; text = *end == ',' ? end + 1 : end)
        out[n_out++] = (fmi3ValueReference)strtoul(text, &end, 10);
    snprintf(path, sizeof path, "%s/binaries/x86_64-linux/%s.so", argv[1], argv[2]);
    lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "%s\n", dlerror());
        return 2;
    }
#define F(T, name) T *name = (T *)(size_t)dlsym(lib, #name)
    F(fmi3InstantiateCoSimulationTYPE, fmi3InstantiateCoSimulation);
    F(fmi3EnterInitializationModeTYPE, fmi3EnterInitializationMode);
    F(fmi3ExitInitializationModeTYPE, fmi3ExitInitializationMode);
    F(fmi3SetFloat64TYPE, fmi3SetFloat64);
    F(fmi3GetFloat64TYPE, fmi3GetFloat64);
    F(fmi3DoStepTYPE, fmi3DoStep);
    F(fmi3TerminateTYPE, fmi3Terminate);
    F(fmi3FreeInstanceTYPE, fmi3FreeInstance);
    if (fmi3InstantiateCoSimulation("bad", "{not the token}", NULL, fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0,
                                    NULL, logger, NULL))
        return 3;
    c = fmi3InstantiateCoSimulation("plant", argv[3], NULL, fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, NULL,
                                    logger, NULL);
    if (!c || fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0) || fmi3ExitInitializationMode(c))
        return 2;
    vr = 100000;
    if (fmi3GetFloat64(c, &vr, 1, &x, 1) != fmi3Error) return 3;
    for (k = 0; k < steps; k++) {
        if (k == k0 && fmi3SetFloat64(c, &in_vr, 1, &value, 1)) return 2;
        if (fmi3DoStep(c, k * h, h, fmi3True, &ev, &term, &early, &last)) return 2;
        if (fmi3GetFloat64(c, out, n_out, y, n_out)) return 2;
        printf("%ld", k);
        for (i = 0; i < n_out; i++) printf(" %.17g", y[i]);
        printf("\n");
    }
    if (fmi3Terminate(c)) return 2;
    fmi3FreeInstance(c);
    dlclose(lib);
    return 0;
}
