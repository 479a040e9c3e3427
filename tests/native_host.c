/* A minimal FMI 2.0 Co-Simulation importer with no Python in the process: dlopen a native FMU's library,
 * run a fixed-input flight and write every requested output at every step as CSV.
 *
 * usage: native_host LIB GUID RESOURCE_URI STEPS STEP_S "vr=value,..." "vr,vr,..." OUT.csv [REPEATS]
 * Prints "us_per_step <median over REPEATS runs of the timed loop>" (SetReal + DoStep + GetReal).
 * Exit status: 0 ok, 2 usage, 3 load, 4 an FMI call failed.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

#define MAXV 256

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s %d %s] ", name, (int)status, category);
    vfprintf(stderr, message, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int cmp(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

#define LOAD(name) \
    name##TYPE* name = (name##TYPE*)dlsym(lib, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 3; }

#define CHECK(call) \
    if ((call) > fmi2Warning) { fprintf(stderr, "failed: %s\n", #call); return 4; }

int main(int argc, char** argv) {
    if (argc < 9) {
        fprintf(stderr, "usage: %s LIB GUID RESOURCE_URI STEPS STEP_S IN OUT_VRS OUT.csv [REPEATS]\n", argv[0]);
        return 2;
    }
    void* lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "dlopen: %s\n", dlerror()); return 3; }
    LOAD(fmi2Instantiate) LOAD(fmi2FreeInstance) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2SetReal) LOAD(fmi2GetReal) LOAD(fmi2DoStep) LOAD(fmi2Terminate)
    LOAD(fmi2Reset)
    long steps = atol(argv[4]);
    double h = atof(argv[5]);
    int repeats = argc > 9 ? atoi(argv[9]) : 1;
    fmi2ValueReference in_vr[MAXV], out_vr[MAXV];
    double in_val[MAXV], out_val[MAXV];
    size_t nin = 0, nout = 0;
    for (char* tok = strtok(argv[6], ","); tok && nin < MAXV; tok = strtok(NULL, ",")) {
        char* eq = strchr(tok, '=');
        if (!eq) return 2;
        in_vr[nin] = (fmi2ValueReference)atol(tok);
        in_val[nin++] = atof(eq + 1);
    }
    for (char* tok = strtok(argv[7], ","); tok && nout < MAXV; tok = strtok(NULL, ","))
        out_vr[nout++] = (fmi2ValueReference)atol(tok);
    FILE* out = fopen(argv[8], "w");
    if (!out) return 2;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("host", fmi2CoSimulation, argv[2], argv[3], &cb, fmi2False, fmi2False);
    if (!c) { fprintf(stderr, "fmi2Instantiate failed\n"); return 4; }
    double* runs = (double*)calloc((size_t)repeats, sizeof(double));
    for (int r = 0; r < repeats; ++r) {
        if (r) CHECK(fmi2Reset(c))
        CHECK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0))
        CHECK(fmi2EnterInitializationMode(c))
        CHECK(fmi2SetReal(c, in_vr, nin, in_val))
        CHECK(fmi2ExitInitializationMode(c))
        double t = 0.0, t0 = now_s();
        for (long k = 0; k < steps; ++k) {
            CHECK(fmi2SetReal(c, in_vr, nin, in_val))
            CHECK(fmi2DoStep(c, t, h, fmi2True))
            CHECK(fmi2GetReal(c, out_vr, nout, out_val))
            t = (k + 1) * h;
            if (r == 0) {
                fprintf(out, "%.17g", t);
                for (size_t i = 0; i < nout; ++i) fprintf(out, ",%.17g", out_val[i]);
                fprintf(out, "\n");
            }
        }
        runs[r] = (now_s() - t0) / (double)steps;
        if (r == 0) fclose(out);
        if (r == 0 && repeats > 1) runs[r] = 1e9; /* the first run writes the file: not timed */
    }
    qsort(runs, (size_t)repeats, sizeof(double), cmp);
    printf("us_per_step %.4f\n", 1e6 * runs[(repeats - 1) / 2]);
    CHECK(fmi2Terminate(c))
    fmi2FreeInstance(c);
    free(runs);
    dlclose(lib);
    return 0;
}
