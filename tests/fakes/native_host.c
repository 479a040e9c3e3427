/* A minimal FMI importer with no Python in the process: dlopen a native FMU's library, run a fixed-input
 * flight and write every requested output at every step as CSV. FMI 2.0 and 3.0, Co-Simulation (the FMU
 * steps) or Model Exchange (this host integrates the FMU's derivatives with its own fixed-step RK4).
 *
 * usage: native_host LIB GUID RESOURCE STEPS STEP_S "vr=value,..." "vr,vr,..." OUT.csv [REPEATS [MODE [NX]]]
 *   MODE: 2cs (default), 2me, 3cs, 3me; NX: number of continuous states (FMI 2.0 Model Exchange)
 *   RESOURCE: the resources URI (FMI 2.0) or path (FMI 3.0)
 * Prints "us_per_step <median over REPEATS runs of the timed loop>" (set inputs + step + get outputs).
 * Exit status: 0 ok, 2 usage, 3 load, 4 an FMI call failed.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"

#define MAXV 256
#define MAXX 64

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    (void)env;
    va_list ap;
    va_start(ap, message);
    fprintf(stderr, "[%s %d %s] ", name, (int)status, category);
    vfprintf(stderr, message, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    fprintf(stderr, "[fmi3 %d %s] %s\n", (int)status, category, message);
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

static void* lib;
static int version = 2, me = 0;
static size_t nx = 0, nin = 0, nout = 0;
static void* comp;
static unsigned in_vr[MAXV], out_vr[MAXV];
static double in_val[MAXV], out_val[MAXV];

/* the FMI function `name`, looked up once (a missing one fails the call that needs it) */
#define SYM(name)                                                    \
    static name##TYPE* name = NULL;                                  \
    if (!name) name = (name##TYPE*)dlsym(lib, #name);                \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 3; }
#define CHECK(call) \
    if ((call) > 1) { fprintf(stderr, "failed: %s\n", #call); return 4; }

static int set_inputs(void) {
    if (version == 2) { SYM(fmi2SetReal); CHECK(fmi2SetReal(comp, in_vr, nin, in_val)) }
    else { SYM(fmi3SetFloat64); CHECK(fmi3SetFloat64(comp, in_vr, nin, in_val, nin)) }
    return 0;
}

static int get_outputs(void) {
    if (version == 2) { SYM(fmi2GetReal); CHECK(fmi2GetReal(comp, out_vr, nout, out_val)) }
    else { SYM(fmi3GetFloat64); CHECK(fmi3GetFloat64(comp, out_vr, nout, out_val, nout)) }
    return 0;
}

/* instantiate (once), initialise with the inputs, and (Model Exchange) enter continuous-time mode */
static int start(const char* guid, const char* resource, int first) {
    if (version == 2) {
        static fmi2CallbackFunctions cb = {logger2, calloc, free, NULL, NULL};
        SYM(fmi2Instantiate); SYM(fmi2Reset); SYM(fmi2SetupExperiment); SYM(fmi2EnterInitializationMode);
        SYM(fmi2ExitInitializationMode);
        if (first) comp = fmi2Instantiate("host", me ? fmi2ModelExchange : fmi2CoSimulation, guid, resource, &cb,
                                          fmi2False, fmi2False);
        else CHECK(fmi2Reset(comp))
        if (!comp) { fprintf(stderr, "fmi2Instantiate failed\n"); return 4; }
        CHECK(fmi2SetupExperiment(comp, fmi2False, 0.0, 0.0, fmi2False, 0.0))
        CHECK(fmi2EnterInitializationMode(comp))
        if (set_inputs()) return 4;
        CHECK(fmi2ExitInitializationMode(comp))
        if (me) {
            SYM(fmi2NewDiscreteStates); SYM(fmi2EnterContinuousTimeMode);
            fmi2EventInfo info;
            do { CHECK(fmi2NewDiscreteStates(comp, &info)) } while (info.newDiscreteStatesNeeded);
            CHECK(fmi2EnterContinuousTimeMode(comp))
        }
        return 0;
    }
    SYM(fmi3InstantiateCoSimulation); SYM(fmi3InstantiateModelExchange); SYM(fmi3Reset);
    SYM(fmi3EnterInitializationMode); SYM(fmi3ExitInitializationMode);
    if (first)
        comp = me ? fmi3InstantiateModelExchange("host", guid, resource, fmi3False, fmi3False, NULL, logger3)
                  : fmi3InstantiateCoSimulation("host", guid, resource, fmi3False, fmi3False, fmi3False, fmi3False,
                                                NULL, 0, NULL, logger3, NULL);
    else CHECK(fmi3Reset(comp))
    if (!comp) { fprintf(stderr, "fmi3Instantiate failed\n"); return 4; }
    CHECK(fmi3EnterInitializationMode(comp, fmi3False, 0.0, 0.0, fmi3False, 0.0))
    if (set_inputs()) return 4;
    CHECK(fmi3ExitInitializationMode(comp))
    if (me) {
        SYM(fmi3UpdateDiscreteStates); SYM(fmi3EnterContinuousTimeMode); SYM(fmi3GetNumberOfContinuousStates);
        fmi3Boolean need = fmi3True, term, nom, val, next_def;
        fmi3Float64 next;
        while (need) CHECK(fmi3UpdateDiscreteStates(comp, &need, &term, &nom, &val, &next_def, &next))
        CHECK(fmi3EnterContinuousTimeMode(comp))
        CHECK(fmi3GetNumberOfContinuousStates(comp, &nx))
        if (nx > MAXX) { fprintf(stderr, "%zu continuous states, at most %d\n", nx, MAXX); return 4; }
    }
    return 0;
}

/* dx/dt at (t, x) */
static int derivatives(double t, const double* x, double* dx) {
    if (version == 2) {
        SYM(fmi2SetTime); SYM(fmi2SetContinuousStates); SYM(fmi2GetDerivatives);
        CHECK(fmi2SetTime(comp, t)) CHECK(fmi2SetContinuousStates(comp, x, nx)) CHECK(fmi2GetDerivatives(comp, dx, nx))
    } else {
        SYM(fmi3SetTime); SYM(fmi3SetContinuousStates); SYM(fmi3GetContinuousStateDerivatives);
        CHECK(fmi3SetTime(comp, t)) CHECK(fmi3SetContinuousStates(comp, x, nx))
        CHECK(fmi3GetContinuousStateDerivatives(comp, dx, nx))
    }
    return 0;
}

/* one step of h from t: the FMU's own (Co-Simulation) or this host's classic RK4 (Model Exchange) */
static int step(double t, double h) {
    if (!me && version == 2) { SYM(fmi2DoStep); CHECK(fmi2DoStep(comp, t, h, fmi2True)) return 0; }
    if (!me) {
        SYM(fmi3DoStep);
        fmi3Boolean ev, term, early;
        fmi3Float64 last;
        CHECK(fmi3DoStep(comp, t, h, fmi3True, &ev, &term, &early, &last))
        return 0;
    }
    double x[MAXX], k[4][MAXX], xs[MAXX];
    if (version == 2) { SYM(fmi2GetContinuousStates); CHECK(fmi2GetContinuousStates(comp, x, nx)) }
    else { SYM(fmi3GetContinuousStates); CHECK(fmi3GetContinuousStates(comp, x, nx)) }
    static const double c[4] = {0.0, 0.5, 0.5, 1.0};
    for (int s = 0; s < 4; ++s) {
        for (size_t i = 0; i < nx; ++i) xs[i] = x[i] + (s ? c[s] * h * k[s - 1][i] : 0.0);
        if (derivatives(t + c[s] * h, xs, k[s])) return 4;
    }
    for (size_t i = 0; i < nx; ++i) x[i] += h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
    if (version == 2) {
        SYM(fmi2SetTime); SYM(fmi2SetContinuousStates); SYM(fmi2CompletedIntegratorStep);
        fmi2Boolean enter, term;
        CHECK(fmi2SetTime(comp, t + h)) CHECK(fmi2SetContinuousStates(comp, x, nx))
        CHECK(fmi2CompletedIntegratorStep(comp, fmi2True, &enter, &term))
    } else {
        SYM(fmi3SetTime); SYM(fmi3SetContinuousStates); SYM(fmi3CompletedIntegratorStep);
        fmi3Boolean enter, term;
        CHECK(fmi3SetTime(comp, t + h)) CHECK(fmi3SetContinuousStates(comp, x, nx))
        CHECK(fmi3CompletedIntegratorStep(comp, fmi3True, &enter, &term))
    }
    return 0;
}

int main(int argc, char** argv) {
    if (argc < 9) {
        fprintf(stderr, "usage: %s LIB GUID RESOURCE STEPS STEP_S IN OUT_VRS OUT.csv [REPEATS [MODE [NX]]]\n", argv[0]);
        return 2;
    }
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "dlopen: %s\n", dlerror()); return 3; }
    long steps = atol(argv[4]);
    double h = atof(argv[5]);
    int repeats = argc > 9 ? atoi(argv[9]) : 1;
    const char* mode = argc > 10 ? argv[10] : "2cs";
    version = mode[0] == '3' ? 3 : 2;
    me = strcmp(mode + 1, "me") == 0;
    nx = argc > 11 ? (size_t)atol(argv[11]) : 0;
    if (repeats < 1 || steps < 1 || nx > MAXX) return 2;
    for (char* tok = strtok(argv[6], ","); tok && nin < MAXV; tok = strtok(NULL, ",")) {
        char* eq = strchr(tok, '=');
        if (!eq) return 2;
        in_vr[nin] = (unsigned)atol(tok);
        in_val[nin++] = atof(eq + 1);
    }
    for (char* tok = strtok(argv[7], ","); tok && nout < MAXV; tok = strtok(NULL, ","))
        out_vr[nout++] = (unsigned)atol(tok);
    FILE* out = fopen(argv[8], "w");
    if (!out) return 2;
    double* runs = (double*)calloc((size_t)repeats, sizeof(double));
    for (int r = 0; r < repeats; ++r) {
        if (start(argv[2], argv[3], r == 0)) return 4;
        double t = 0.0, t0 = now_s();
        for (long k = 0; k < steps; ++k) {
            if (set_inputs() || step(t, h) || get_outputs()) return 4;
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
    if (version == 2) {
        SYM(fmi2Terminate); SYM(fmi2FreeInstance);
        CHECK(fmi2Terminate(comp))
        fmi2FreeInstance(comp);
    } else {
        SYM(fmi3Terminate); SYM(fmi3FreeInstance);
        CHECK(fmi3Terminate(comp))
        fmi3FreeInstance(comp);
    }
    free(runs);
    dlclose(lib);
    return 0;
}
