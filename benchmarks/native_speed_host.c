/*
 * Steps per second of an FMI 2.0 co-simulation FMU in a plain C host (benchmarks/native_speed.py).
 *
 *   native_speed_host UNZIPDIR MODEL_IDENTIFIER GUID STEPS H IN_VRS REAL_VRS BOOL_VRS INT_VRS
 *
 * (VRS: comma-separated value references.) One step = fmi2SetReal(inputs) + fmi2DoStep +
 * fmi2GetReal / fmi2GetBoolean / fmi2GetInteger of every output. Inputs cycle through 1024 rows
 * of fixed pseudo-random numbers. Prints "<CPU seconds per step> <checksum>" (process CPU time:
 * a machine shared with other jobs slows the wall clock, not this).
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2FunctionTypes.h"

static void logger(fmi2ComponentEnvironment e, fmi2String i, fmi2Status s, fmi2String c, fmi2String m, ...) {
    (void)e; (void)i; (void)c;
    if (s >= fmi2Error) fprintf(stderr, "FMU: %s\n", m);
}

static int vrs(const char *text, unsigned *out, int max) {
    int n = 0;
    char *end;
    while (*text && n < max) {
        out[n++] = (unsigned)strtoul(text, &end, 10);
        text = *end == ',' ? end + 1 : end;
        if (end == text && *text) return -1;
    }
    return n;
}

int main(int argc, char **argv) {
    char path[8192];
    void *lib;
    fmi2Component c;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    unsigned vr_in[64], vr_r[256], vr_b[256], vr_i[256];
    int n_in, nr, nb, ni, k, j;
    long steps;
    double h, *data, out_r[256], sum = 0.0, t0, t1;
    int out_b[256], out_i[256];
    unsigned long long seed = 12345u;
    struct timespec ts;
    if (argc != 10) {
        fprintf(stderr, "usage: native_speed_host UNZIPDIR ID GUID STEPS H IN_VRS REAL_VRS BOOL_VRS INT_VRS\n");
        return 1;
    }
    steps = atol(argv[4]);
    h = atof(argv[5]);
    n_in = vrs(argv[6], vr_in, 64);
    nr = vrs(argv[7], vr_r, 256);
    nb = vrs(argv[8], vr_b, 256);
    ni = vrs(argv[9], vr_i, 256);
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", argv[1], argv[2]);
    lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "%s\n", dlerror());
        return 2;
    }
#define F(T, name) T *name = (T *)(size_t)dlsym(lib, #name)
    F(fmi2InstantiateTYPE, fmi2Instantiate);
    F(fmi2SetupExperimentTYPE, fmi2SetupExperiment);
    F(fmi2EnterInitializationModeTYPE, fmi2EnterInitializationMode);
    F(fmi2ExitInitializationModeTYPE, fmi2ExitInitializationMode);
    F(fmi2SetRealTYPE, fmi2SetReal);
    F(fmi2GetRealTYPE, fmi2GetReal);
    F(fmi2GetBooleanTYPE, fmi2GetBoolean);
    F(fmi2GetIntegerTYPE, fmi2GetInteger);
    F(fmi2DoStepTYPE, fmi2DoStep);
    F(fmi2FreeInstanceTYPE, fmi2FreeInstance);
    snprintf(path, sizeof path, "file://%s/resources", argv[1]);
    c = fmi2Instantiate("bench", fmi2CoSimulation, argv[3], path, &cb, fmi2False, fmi2False);
    if (!c || fmi2SetupExperiment(c, fmi2False, 0, 0, fmi2False, 0) || fmi2EnterInitializationMode(c) ||
        fmi2ExitInitializationMode(c))
        return 2;
    data = malloc(sizeof(double) * 1024 * (size_t)n_in);
    for (j = 0; j < 1024 * n_in; j++) {  /* xorshift, uniform in [-1, 1) */
        seed ^= seed << 13; seed ^= seed >> 7; seed ^= seed << 17;
        data[j] = (double)(seed >> 11) / 4503599627370496.0 - 1.0;
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    t0 = ts.tv_sec + 1e-9 * ts.tv_nsec;
    for (k = 0; k < steps; k++) {
        if (fmi2SetReal(c, vr_in, (size_t)n_in, &data[(k & 1023) * n_in]) ||
            fmi2DoStep(c, k * h, h, fmi2True) || fmi2GetReal(c, vr_r, (size_t)nr, out_r) ||
            fmi2GetBoolean(c, vr_b, (size_t)nb, out_b) || fmi2GetInteger(c, vr_i, (size_t)ni, out_i))
            return 2;
        sum += out_r[0] + out_b[0] + out_i[0];
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    t1 = ts.tv_sec + 1e-9 * ts.tv_nsec;
    fmi2FreeInstance(c);
    free(data);
    printf("%.6g %.17g\n", (t1 - t0) / (double)steps, sum);
    return 0;
}
