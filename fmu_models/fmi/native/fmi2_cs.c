/* FMI 2.0 Co-Simulation layer of the uavfmu native FMUs, shared by every vehicle (see uavfmu_model.h).
 *
 * Hand-written in the style of modelica/Reference-FMUs (src/fmi2Functions.c): every call is checked
 * against the FMI 2.0 Co-Simulation state machine (spec 2.0.4, section 4.2.4) and its arguments (NULL
 * pointers, value references, variable types and causalities, sizes, communication time, FMU-state
 * ownership) before the model sees it. A wrong call returns fmi2Error and logs why; the instance stays
 * usable for fmi2Reset and fmi2FreeInstance. Errors and warnings are always logged (an importer must see
 * them whatever its debug-logging setting); OK-level messages only with debug logging on.
 *
 * Model failures as in the pythonfmu backend: a NaN or out-of-range input or parameter, or a diverging
 * integration, makes fmi2DoStep return fmi2Error with a logged message; the instance goes to the Error
 * state, from which fmi2Reset starts again.
 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "uavfmu_model.h"

#define INSTANCE_MAGIC 0x5541564641554d31ULL /* "UAVFMU1" */
#define STATE_MAGIC 0x5541564653544154ULL    /* "UAVFSTAT" */
#define SERIAL_TAG "uavfmu-fmu-state-1"

typedef enum {
    StartAndEnd = 1 << 0,
    Instantiated = 1 << 1,
    InitializationMode = 1 << 2,
    StepComplete = 1 << 5,
    StepInProgress = 1 << 6,
    StepFailed = 1 << 7,
    StepCanceled = 1 << 8,
    Terminated = 1 << 9,
    Error = 1 << 10,
} ModelState;

#define ALL_LIVE (Instantiated | InitializationMode | StepComplete | StepFailed | StepCanceled | Terminated | Error)
#define MASK_SetDebugLogging ALL_LIVE
#define MASK_SetupExperiment Instantiated
#define MASK_EnterInitializationMode Instantiated
#define MASK_ExitInitializationMode InitializationMode
/* Error too: importers commonly terminate after a failed step; harmless, and the instance stays resettable */
#define MASK_Terminate (StepComplete | StepFailed | Error)
#define MASK_Reset ALL_LIVE
#define MASK_GetValue (InitializationMode | StepComplete | StepFailed | StepCanceled | Terminated | Error)
#define MASK_SetValue (Instantiated | InitializationMode | StepComplete)
#define MASK_FMUstate (Instantiated | InitializationMode | StepComplete | StepFailed | StepCanceled | Terminated | Error)
#define MASK_DoStep StepComplete
#define MASK_GetStatus (StepComplete | StepFailed | Terminated)

struct FmuState;

typedef struct Instance {
    uint64_t magic;
    const uavfmu_model_info* model;
    char* name;
    fmi2CallbackFunctions cb;
    int logging_on;
    ModelState state;
    double time;          /* last communication point (s) */
    double start_time;
    int params_dirty;
    int init_valid;       /* y holds the outputs of the current x (after exit init or a step) */
    double *x, *x_next, *u, *p, *y;
    unsigned char* warned; /* per output: warning already logged this run */
    int* kinds;              /* variable indices: inputs, then parameters, then outputs with a warning */
    int n_in, n_par, n_warn;
    struct FmuState* states; /* every FMU state this instance handed out, freed with it */
    char message[512];
} Instance;

typedef struct FmuState {
    uint64_t magic;
    Instance* owner;
    struct FmuState* next;
    ModelState state;
    double time, start_time;
    int params_dirty, init_valid;
    double* values; /* x, u, p, y */
    unsigned char* warned;
} FmuState;

/* ------------------------------------------------------------------ logging */

static void log_text(Instance* c, fmi2Status status, const char* category, const char* text) {
    if (!c->cb.logger) return;
    if (status == fmi2OK && !c->logging_on) return;
    /* the logger takes a printf format: escape '%' so any text is safe */
    char buf[1100];
    size_t j = 0;
    for (size_t i = 0; text[i] && j + 2 < sizeof buf; ++i) {
        if (text[i] == '%') buf[j++] = '%';
        buf[j++] = text[i];
    }
    buf[j] = 0;
    c->cb.logger(c->cb.componentEnvironment, c->name, status, category, buf);
}

static fmi2Status fail(Instance* c, fmi2Status status, const char* fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->message, sizeof c->message, fmt, ap);
    va_end(ap);
    log_text(c, status, status == fmi2Warning ? "logStatusWarning"
                        : status == fmi2Discard ? "logStatusDiscard" : "logStatusError", c->message);
    return status;
}

static const char* state_name(ModelState s) {
    switch (s) {
    case StartAndEnd: return "start/end";
    case Instantiated: return "instantiated";
    case InitializationMode: return "initialization mode";
    case StepComplete: return "step complete";
    case StepInProgress: return "step in progress";
    case StepFailed: return "step failed";
    case StepCanceled: return "step canceled";
    case Terminated: return "terminated";
    case Error: return "error";
    }
    return "unknown";
}

/* The component, if it is one of ours, else NULL (never writes through a foreign pointer). */
static Instance* check(fmi2Component comp, int mask, const char* fn) {
    Instance* c = (Instance*)comp;
    if (!c || c->magic != INSTANCE_MAGIC || c->model != &uavfmu_model) return NULL;
    if (!(c->state & mask)) {
        fail(c, fmi2Error, "%s: not allowed in state '%s' (FMI 2.0 Co-Simulation state machine)", fn,
             state_name(c->state));
        return NULL;
    }
    return c;
}

#define BEGIN(fn, mask)                                   \
    Instance* c = check(comp, mask, fn);                  \
    if (!c) return fmi2Error;

/* ------------------------------------------------------------------ instance */

static void set_starts(Instance* c) {
    const uavfmu_model_info* m = c->model;
    for (int i = 0; i < m->n_variables; ++i) {
        const uavfmu_variable* v = &m->variables[i];
        if (v->causality == UAVFMU_INPUT) c->u[v->index] = v->start;
        else if (v->causality == UAVFMU_PARAMETER) c->p[v->index] = v->start;
    }
    memset(c->x, 0, sizeof(double) * (size_t)(m->nx ? m->nx : 1));
    memset(c->y, 0, sizeof(double) * (size_t)(m->ny ? m->ny : 1));
    memset(c->warned, 0, (size_t)(m->ny ? m->ny : 1));
    c->time = 0.0;
    c->start_time = 0.0;
    c->params_dirty = 1;
    c->init_valid = 0;
}

static void free_state(FmuState* s) {
    if (!s) return;
    s->magic = 0;
    free(s->values);
    free(s->warned);
    free(s);
}

static void free_instance(Instance* c) {
    if (!c) return;
    FmuState* s = c->states;
    while (s) {
        FmuState* n = s->next;
        free_state(s);
        s = n;
    }
    c->magic = 0;
    free(c->x);
    free(c->kinds);
    free(c->warned);
    free(c->name);
    free(c);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions* functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions) return NULL;
    const uavfmu_model_info* m = &uavfmu_model;
    Instance tmp;
    memset(&tmp, 0, sizeof tmp);
    tmp.cb = *functions;
    tmp.name = (char*)(instanceName ? instanceName : "?");
    if (!instanceName || !instanceName[0]) {
        fail(&tmp, fmi2Error, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        fail(&tmp, fmi2Error, "fmi2Instantiate: %s supports Co-Simulation only (fmuType %d)", m->name, (int)fmuType);
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, m->guid) != 0) {
        fail(&tmp, fmi2Error, "fmi2Instantiate: GUID %s does not match this binary's %s", fmuGUID ? fmuGUID : "(null)",
             m->guid);
        return NULL;
    }
    Instance* c = (Instance*)calloc(1, sizeof(Instance));
    size_t n = (size_t)(2 * m->nx + m->nu + m->np + m->ny) + 5;
    if (c) {
        c->x = (double*)calloc(n, sizeof(double));
        c->warned = (unsigned char*)calloc((size_t)m->ny + 1, 1);
        c->kinds = (int*)calloc((size_t)m->n_variables + 1, sizeof(int));
        c->name = (char*)malloc(strlen(instanceName) + 1);
    }
    if (!c || !c->x || !c->warned || !c->kinds || !c->name) {
        if (c) { free(c->x); free(c->warned); free(c->kinds); free(c->name); free(c); }
        fail(&tmp, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    strcpy(c->name, instanceName);
    c->x_next = c->x + m->nx + 1;
    c->u = c->x_next + m->nx + 1;
    c->p = c->u + m->nu + 1;
    c->y = c->p + m->np + 1;
    for (int i = 0; i < m->n_variables; ++i) {
        const uavfmu_variable* v = &m->variables[i];
        c->n_in += v->causality == UAVFMU_INPUT;
        c->n_par += v->causality == UAVFMU_PARAMETER;
        c->n_warn += v->causality == UAVFMU_OUTPUT && v->warning != NULL;
    }
    for (int i = 0, a = 0, b = c->n_in, w = c->n_in + c->n_par; i < m->n_variables; ++i) {
        const uavfmu_variable* v = &m->variables[i];
        if (v->causality == UAVFMU_INPUT) c->kinds[a++] = i;
        else if (v->causality == UAVFMU_PARAMETER) c->kinds[b++] = i;
        else if (v->warning) c->kinds[w++] = i;
    }
    c->magic = INSTANCE_MAGIC;
    c->model = m;
    c->cb = *functions;
    c->logging_on = loggingOn ? 1 : 0;
    c->state = Instantiated;
    set_starts(c);
    return c;
}

void fmi2FreeInstance(fmi2Component comp) {
    Instance* c = (Instance*)comp;
    if (!c || c->magic != INSTANCE_MAGIC || c->model != &uavfmu_model) return;
    free_instance(c);
}

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    BEGIN("fmi2SetDebugLogging", MASK_SetDebugLogging)
    if (nCategories > 0 && !categories) return fail(c, fmi2Error, "fmi2SetDebugLogging: categories is NULL");
    for (size_t i = 0; i < nCategories; ++i) {
        const char* k = categories[i];
        if (!k || (strcmp(k, "logStatusWarning") && strcmp(k, "logStatusDiscard") && strcmp(k, "logStatusError") &&
                   strcmp(k, "logStatusFatal") && strcmp(k, "logAll")))
            return fail(c, fmi2Error, "fmi2SetDebugLogging: unknown log category %s", k ? k : "(null)");
    }
    c->logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN("fmi2SetupExperiment", MASK_SetupExperiment)
    (void)toleranceDefined;
    (void)tolerance;
    if (!isfinite(startTime)) return fail(c, fmi2Error, "fmi2SetupExperiment: startTime %g is not finite", startTime);
    if (stopTimeDefined && !(stopTime >= startTime))
        return fail(c, fmi2Error, "fmi2SetupExperiment: stopTime %g is before startTime %g", stopTime, startTime);
    c->start_time = startTime;
    c->time = startTime;
    return fmi2OK;
}

/* A call that only moves the instance (allowed in the states of `mask`) to state `to`. */
static fmi2Status move_to(fmi2Component comp, const char* fn, int mask, ModelState to) {
    BEGIN(fn, mask)
    c->state = to;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    return move_to(comp, "fmi2EnterInitializationMode", MASK_EnterInitializationMode, InitializationMode);
}

/* Python's repr of a float (shortest round-trip, "3100.0", "nan"), so messages read as the pythonfmu backend's */
static const char* num(double v, char* buf, size_t n) {
    if (v != v) return "nan";
    if (isinf(v)) return v > 0 ? "inf" : "-inf";
    int prec = 1;
    for (; prec <= 17; ++prec) {
        snprintf(buf, n, "%.*e", prec - 1, v);
        if (strtod(buf, NULL) == v) break;
    }
    double a = fabs(v);
    if (a == 0.0 || (a >= 1e-4 && a < 1e16)) {
        const char* e = strchr(buf, 'e');
        int exp10 = e ? atoi(e + 1) : 0;
        int decimals = prec - 1 - exp10;
        snprintf(buf, n, "%.*f", decimals < 1 ? 1 : decimals, v);
    }
    return buf;
}

/* "" if every value of kind (input or parameter) is finite and inside [min, max], else a message */
static int check_values(Instance* c, int causality, const char* when) {
    const uavfmu_model_info* m = c->model;
    const double* arr = causality == UAVFMU_INPUT ? c->u : c->p;
    const int* list = causality == UAVFMU_INPUT ? c->kinds : c->kinds + c->n_in;
    int n = causality == UAVFMU_INPUT ? c->n_in : c->n_par;
    for (int k = 0; k < n; ++k) {
        const uavfmu_variable* v = &m->variables[list[k]];
        double val = arr[v->index];
        if (val != val || (v->has_min && val < v->min) || (v->has_max && val > v->max) || isinf(val)) {
            char a[40], b[40], d[40];
            fail(c, fmi2Error, "%s: %s %s = %s is outside its allowed range [%s, %s]", when,
                 causality == UAVFMU_INPUT ? "input" : "parameter", v->name, num(val, a, sizeof a),
                 v->has_min ? num(v->min, b, sizeof b) : "None", v->has_max ? num(v->max, d, sizeof d) : "None");
            return 1;
        }
    }
    return 0;
}

static const char* diverged(Instance* c, int status, char* buf, size_t n) {
    const uavfmu_model_info* m = c->model;
    if (status > 0 && status <= m->nx)
        snprintf(buf, n, "state %s left [-%g, %g] %s or became NaN", m->state_names[status - 1],
                 m->state_limits[status - 1], m->state_limits[status - 1], m->state_units[status - 1]);
    else if (status < 0 && -status <= m->ny) {
        const char* name = "?";
        for (int i = 0; i < m->n_variables; ++i)
            if (m->variables[i].causality == UAVFMU_OUTPUT && m->variables[i].index == -status - 1)
                name = m->variables[i].name;
        snprintf(buf, n, "output %s became NaN or infinite", name);
    } else
        snprintf(buf, n, "the generated model code failed (code %d)", status);
    return buf;
}

/* x and y from the current inputs and parameters */
static fmi2Status initialize(Instance* c, const char* when) {
    char why[256];
    if (check_values(c, UAVFMU_PARAMETER, when)) return fmi2Error;
    int s = uavfmu_initialize(c->u, c->p, c->x, c->y);
    if (s) return fail(c, fmi2Error, "%s: the initial state is not finite (%s)", when, diverged(c, s, why, sizeof why));
    c->params_dirty = 0;
    c->init_valid = 1;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    BEGIN("fmi2ExitInitializationMode", MASK_ExitInitializationMode)
    memset(c->warned, 0, (size_t)c->model->ny + 1);
    if (initialize(c, "initialisation") != fmi2OK) {
        c->state = Error;
        return fmi2Error;
    }
    c->time = c->start_time;
    c->state = StepComplete;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component comp) {
    return move_to(comp, "fmi2Terminate", MASK_Terminate, Terminated);
}

fmi2Status fmi2Reset(fmi2Component comp) {
    BEGIN("fmi2Reset", MASK_Reset)
    set_starts(c);
    c->state = Instantiated;
    return fmi2OK;
}

/* ------------------------------------------------------------------ get / set */

static const uavfmu_variable* lookup(Instance* c, fmi2ValueReference vr, const char* fn, int want_boolean) {
    const uavfmu_model_info* m = c->model;
    if (vr >= (fmi2ValueReference)m->n_variables) {
        fail(c, fmi2Error, "%s: unknown value reference %u (this FMU has 0..%d)", fn, (unsigned)vr, m->n_variables - 1);
        return NULL;
    }
    const uavfmu_variable* v = &m->variables[vr];
    if (v->boolean != want_boolean) {
        fail(c, fmi2Error, "%s: value reference %u (%s) is a %s variable", fn, (unsigned)vr, v->name,
             v->boolean ? "Boolean" : "Real");
        return NULL;
    }
    return v;
}

static double* slot(Instance* c, const uavfmu_variable* v) {
    return v->causality == UAVFMU_INPUT ? &c->u[v->index]
           : v->causality == UAVFMU_PARAMETER ? &c->p[v->index] : &c->y[v->index];
}

/* outputs asked for in initialization mode: computed from the current inputs and parameters */
static fmi2Status outputs_ready(Instance* c, const char* fn) {
    if (c->state != InitializationMode || (c->init_valid && !c->params_dirty)) return fmi2OK;
    return initialize(c, fn);
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    BEGIN("fmi2GetReal", MASK_GetValue)
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fail(c, fmi2Error, "fmi2GetReal: vr or value is NULL with nvr = %zu", nvr);
    int need_outputs = 0;
    for (size_t i = 0; i < nvr; ++i) {
        const uavfmu_variable* v = lookup(c, vr[i], "fmi2GetReal", 0);
        if (!v) return fmi2Error;
        need_outputs |= v->causality == UAVFMU_OUTPUT;
    }
    if (need_outputs && outputs_ready(c, "fmi2GetReal") != fmi2OK) return fmi2Error;
    const uavfmu_variable* vars = c->model->variables;
    for (size_t i = 0; i < nvr; ++i) value[i] = *slot(c, &vars[vr[i]]);
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    BEGIN("fmi2GetBoolean", MASK_GetValue)
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fail(c, fmi2Error, "fmi2GetBoolean: vr or value is NULL with nvr = %zu", nvr);
    for (size_t i = 0; i < nvr; ++i)
        if (!lookup(c, vr[i], "fmi2GetBoolean", 1)) return fmi2Error;
    if (outputs_ready(c, "fmi2GetBoolean") != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; ++i) value[i] = *slot(c, &c->model->variables[vr[i]]) > 0.5 ? fmi2True : fmi2False;
    return fmi2OK;
}

static fmi2Status no_such_type(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const void* value,
                               const char* fn, int mask) {
    BEGIN(fn, mask)
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fail(c, fmi2Error, "%s: vr or value is NULL with nvr = %zu", fn, nvr);
    if (vr[0] < (fmi2ValueReference)c->model->n_variables)
        return fail(c, fmi2Error, "%s: value reference %u (%s) is a %s variable; this FMU has no variable of this type",
                    fn, (unsigned)vr[0], c->model->variables[vr[0]].name,
                    c->model->variables[vr[0]].boolean ? "Boolean" : "Real");
    return fail(c, fmi2Error, "%s: unknown value reference %u", fn, (unsigned)vr[0]);
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    return no_such_type(comp, vr, nvr, value, "fmi2GetInteger", MASK_GetValue);
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    return no_such_type(comp, vr, nvr, value, "fmi2GetString", MASK_GetValue);
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    return no_such_type(comp, vr, nvr, value, "fmi2SetInteger", MASK_SetValue);
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    return no_such_type(comp, vr, nvr, value, "fmi2SetString", MASK_SetValue);
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    BEGIN("fmi2SetBoolean", MASK_SetValue)
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fail(c, fmi2Error, "fmi2SetBoolean: vr or value is NULL with nvr = %zu", nvr);
    const uavfmu_variable* v = lookup(c, vr[0], "fmi2SetBoolean", 1);
    if (!v) return fmi2Error;
    return fail(c, fmi2Error, "fmi2SetBoolean: %s is an output and cannot be set", v->name);
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    BEGIN("fmi2SetReal", MASK_SetValue)
    if (nvr == 0) return fmi2OK;
    if (!vr || !value) return fail(c, fmi2Error, "fmi2SetReal: vr or value is NULL with nvr = %zu", nvr);
    /* check all first: a rejected call changes nothing */
    for (size_t i = 0; i < nvr; ++i) {
        const uavfmu_variable* v = lookup(c, vr[i], "fmi2SetReal", 0);
        if (!v) return fmi2Error;
        if (v->causality == UAVFMU_OUTPUT)
            return fail(c, fmi2Error, "fmi2SetReal: %s is an output and cannot be set", v->name);
    }
    const uavfmu_variable* vars = c->model->variables;
    for (size_t i = 0; i < nvr; ++i) {
        const uavfmu_variable* v = &vars[vr[i]];
        if (v->causality == UAVFMU_PARAMETER) c->params_dirty = 1;
        else c->init_valid = c->state == InitializationMode ? 0 : c->init_valid;
        *slot(c, v) = value[i];
    }
    return fmi2OK;
}

/* ------------------------------------------------------------------ step */

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    BEGIN("fmi2DoStep", MASK_DoStep)
    (void)noSetFMUStatePriorToCurrentPoint;
    const uavfmu_model_info* m = c->model;
    double t = currentCommunicationPoint, h = communicationStepSize;
    if (!(h > 0.0) || !isfinite(h))
        return fail(c, fmi2Error, "fmi2DoStep: communication step size %g must be finite and > 0", h);
    if (!isfinite(t) || fabs(t - c->time) > 1e-9 * (fabs(c->time) > 1.0 ? fabs(c->time) : 1.0))
        return fail(c, fmi2Error, "fmi2DoStep: currentCommunicationPoint %.17g is not the last communication point "
                    "%.17g", t, c->time);
    char when[64];
    snprintf(when, sizeof when, "t = %g s", t);
    if (check_values(c, UAVFMU_INPUT, when) || (c->params_dirty && check_values(c, UAVFMU_PARAMETER, when))) {
        c->state = Error;
        return fmi2Error;
    }
    c->params_dirty = 0;
    double hh[2] = {h, c->p[m->i_step_internal]};
    int s = uavfmu_advance(c->x, c->u, c->p, hh, c->x_next, c->y);
    if (s) {
        char why[256];
        c->state = Error;
        return fail(c, fmi2Error, "t = %g s: integration diverged: %s", t, diverged(c, s, why, sizeof why));
    }
    memcpy(c->x, c->x_next, sizeof(double) * (size_t)m->nx);
    c->time = t + h;
    for (int k = c->n_in + c->n_par; k < c->n_in + c->n_par + c->n_warn; ++k) {
        const uavfmu_variable* v = &m->variables[c->kinds[k]];
        if (c->y[v->index] > 0.5 && !c->warned[v->index]) {
            c->warned[v->index] = 1;
            fail(c, fmi2Warning, "t = %g s: %s (logged once per run)", c->time, v->warning);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component comp) {
    BEGIN("fmi2CancelStep", ALL_LIVE)
    return fail(c, fmi2Error, "fmi2CancelStep: fmi2DoStep is synchronous here; there is no step to cancel");
}

/* The fmi2Get<Type>Status functions: each answers one status kind (fmi2GetIntegerStatus none, kind -1);
   any other kind is fmi2Discard. */
static fmi2Status get_status(fmi2Component comp, const char* fn, fmi2StatusKind s, int kind, void* value) {
    BEGIN(fn, MASK_GetStatus)
    if (!value) return fail(c, fmi2Error, "%s: value is NULL", fn);
    /* kind -1 (no status of that type) never matches: a caller's (fmi2StatusKind)-1 is not answered either */
    if (kind < 0 || (int)s != kind) return fail(c, fmi2Discard, "%s: status kind %d is not available", fn, (int)s);
    switch (s) {
    case fmi2DoStepStatus: *(fmi2Status*)value = fmi2OK; return fmi2OK; /* fmi2DoStep is synchronous */
    case fmi2PendingStatus: *(fmi2String*)value = ""; return fmi2OK;
    case fmi2LastSuccessfulTime: *(fmi2Real*)value = c->time; return fmi2OK;
    case fmi2Terminated: *(fmi2Boolean*)value = fmi2False; return fmi2OK; /* the FMU never ends the simulation */
    default: return fail(c, fmi2Discard, "%s: status kind %d is not available", fn, (int)s);
    }
}

#define GET_STATUS(Type, TypeName, kind)                                                                       \
    fmi2Status fmi2Get##Type##Status(fmi2Component comp, const fmi2StatusKind s, TypeName* value) {           \
        return get_status(comp, "fmi2Get" #Type "Status", s, kind, value);                                    \
    }
GET_STATUS(, fmi2Status, fmi2DoStepStatus)
GET_STATUS(Real, fmi2Real, fmi2LastSuccessfulTime)
GET_STATUS(Integer, fmi2Integer, -1)
GET_STATUS(Boolean, fmi2Boolean, fmi2Terminated)
GET_STATUS(String, fmi2String, fmi2PendingStatus)
#undef GET_STATUS

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    BEGIN("fmi2SetRealInputDerivatives", ALL_LIVE)
    (void)vr; (void)nvr; (void)order; (void)value;
    return fail(c, fmi2Error, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs is false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    BEGIN("fmi2GetRealOutputDerivatives", ALL_LIVE)
    (void)vr; (void)nvr; (void)order; (void)value;
    return fail(c, fmi2Error, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder is 0)");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    BEGIN("fmi2GetDirectionalDerivative", ALL_LIVE)
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    return fail(c, fmi2Error, "fmi2GetDirectionalDerivative: not supported (providesDirectionalDerivative is false)");
}

/* ------------------------------------------------------------------ FMU state */

static size_t n_values(const uavfmu_model_info* m) { return (size_t)(m->nx + m->nu + m->np + m->ny); }

static FmuState* new_state(Instance* c) {
    FmuState* s = (FmuState*)calloc(1, sizeof(FmuState));
    if (!s) return NULL;
    s->values = (double*)calloc(n_values(c->model) + 1, sizeof(double));
    s->warned = (unsigned char*)calloc((size_t)c->model->ny + 1, 1);
    if (!s->values || !s->warned) {
        free_state(s);
        return NULL;
    }
    s->magic = STATE_MAGIC;
    s->owner = c;
    s->next = c->states;
    c->states = s;
    return s;
}

/* the state if this instance handed it out (compared by address: a foreign pointer is never read) */
static FmuState* owned(Instance* c, fmi2FMUstate state, const char* fn) {
    for (FmuState* s = c->states; s; s = s->next)
        if ((void*)s == (void*)state) return s;
    fail(c, fmi2Error, "%s: the FMU state %p was not created by this instance (or was freed)", fn, (void*)state);
    return NULL;
}

static void copy_to_state(Instance* c, FmuState* s) {
    const uavfmu_model_info* m = c->model;
    double* v = s->values;
    memcpy(v, c->x, sizeof(double) * (size_t)m->nx);
    memcpy(v + m->nx, c->u, sizeof(double) * (size_t)m->nu);
    memcpy(v + m->nx + m->nu, c->p, sizeof(double) * (size_t)m->np);
    memcpy(v + m->nx + m->nu + m->np, c->y, sizeof(double) * (size_t)m->ny);
    memcpy(s->warned, c->warned, (size_t)m->ny);
    s->state = c->state;
    s->time = c->time;
    s->start_time = c->start_time;
    s->params_dirty = c->params_dirty;
    s->init_valid = c->init_valid;
}

/* The FMU state a call fills: `*FMUstate` when this instance handed it out, else (NULL) a new one; NULL after
   logging the error. */
static FmuState* state_to_fill(Instance* c, fmi2FMUstate* FMUstate, const char* fn) {
    if (*FMUstate) return owned(c, *FMUstate, fn);
    FmuState* s = new_state(c);
    if (!s) fail(c, fmi2Error, "%s: out of memory", fn);
    return s;
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate* FMUstate) {
    BEGIN("fmi2GetFMUstate", MASK_FMUstate)
    if (!FMUstate) return fail(c, fmi2Error, "fmi2GetFMUstate: FMUstate is NULL");
    FmuState* s = state_to_fill(c, FMUstate, "fmi2GetFMUstate");
    if (!s) return fmi2Error;
    copy_to_state(c, s);
    *FMUstate = s;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate FMUstate) {
    BEGIN("fmi2SetFMUstate", MASK_FMUstate)
    FmuState* s = owned(c, FMUstate, "fmi2SetFMUstate");
    if (!s) return fmi2Error;
    const uavfmu_model_info* m = c->model;
    const double* v = s->values;
    memcpy(c->x, v, sizeof(double) * (size_t)m->nx);
    memcpy(c->u, v + m->nx, sizeof(double) * (size_t)m->nu);
    memcpy(c->p, v + m->nx + m->nu, sizeof(double) * (size_t)m->np);
    memcpy(c->y, v + m->nx + m->nu + m->np, sizeof(double) * (size_t)m->ny);
    memcpy(c->warned, s->warned, (size_t)m->ny);
    c->state = s->state;
    c->time = s->time;
    c->start_time = s->start_time;
    c->params_dirty = 1; /* re-checked before the next step, as after any parameter change */
    c->init_valid = s->init_valid;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate* FMUstate) {
    BEGIN("fmi2FreeFMUstate", MASK_FMUstate)
    if (!FMUstate) return fail(c, fmi2Error, "fmi2FreeFMUstate: FMUstate is NULL");
    if (!*FMUstate) return fmi2OK;
    FmuState* s = owned(c, *FMUstate, "fmi2FreeFMUstate");
    if (!s) return fmi2Error;
    FmuState** link = &c->states;
    while (*link != s) link = &(*link)->next;
    *link = s->next;
    free_state(s);
    *FMUstate = NULL;
    return fmi2OK;
}

/* serialised layout: tag, guid, 7 int32 (sizes, state, flags), 2 doubles (times), values, warned */
static size_t serial_size(const uavfmu_model_info* m) {
    return sizeof SERIAL_TAG + strlen(m->guid) + 1 + 7 * sizeof(int32_t) + (2 + n_values(m)) * sizeof(double) +
           (size_t)m->ny;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate FMUstate, size_t* size) {
    BEGIN("fmi2SerializedFMUstateSize", MASK_FMUstate)
    if (!size) return fail(c, fmi2Error, "fmi2SerializedFMUstateSize: size is NULL");
    if (!owned(c, FMUstate, "fmi2SerializedFMUstateSize")) return fmi2Error;
    *size = serial_size(c->model);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    BEGIN("fmi2SerializeFMUstate", MASK_FMUstate)
    FmuState* s = owned(c, FMUstate, "fmi2SerializeFMUstate");
    if (!s) return fmi2Error;
    const uavfmu_model_info* m = c->model;
    if (!serializedState) return fail(c, fmi2Error, "fmi2SerializeFMUstate: serializedState is NULL");
    if (size < serial_size(m))
        return fail(c, fmi2Error, "fmi2SerializeFMUstate: buffer of %zu bytes is smaller than the %zu needed", size,
                    serial_size(m));
    char* b = (char*)serializedState;
    int32_t ints[7] = {m->nx, m->nu, m->np, m->ny, (int32_t)s->state, s->params_dirty, s->init_valid};
    double times[2] = {s->time, s->start_time};
    memcpy(b, SERIAL_TAG, sizeof SERIAL_TAG); b += sizeof SERIAL_TAG;
    memcpy(b, m->guid, strlen(m->guid) + 1); b += strlen(m->guid) + 1;
    memcpy(b, ints, sizeof ints); b += sizeof ints;
    memcpy(b, times, sizeof times); b += sizeof times;
    memcpy(b, s->values, n_values(m) * sizeof(double)); b += n_values(m) * sizeof(double);
    memcpy(b, s->warned, (size_t)m->ny);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate* FMUstate) {
    BEGIN("fmi2DeSerializeFMUstate", MASK_FMUstate)
    const uavfmu_model_info* m = c->model;
    if (!serializedState || !FMUstate) return fail(c, fmi2Error, "fmi2DeSerializeFMUstate: NULL argument");
    const char* b = (const char*)serializedState;
    size_t glen = strlen(m->guid) + 1;
    if (size != serial_size(m) || memcmp(b, SERIAL_TAG, sizeof SERIAL_TAG) || memcmp(b + sizeof SERIAL_TAG, m->guid, glen))
        return fail(c, fmi2Error, "fmi2DeSerializeFMUstate: %zu bytes are not a serialised state of this FMU (%s)",
                    size, m->guid);
    b += sizeof SERIAL_TAG + glen;
    int32_t ints[7];
    double times[2];
    memcpy(ints, b, sizeof ints); b += sizeof ints;
    memcpy(times, b, sizeof times); b += sizeof times;
    int known = ints[4] == Instantiated || ints[4] == InitializationMode || ints[4] == StepComplete ||
                ints[4] == StepFailed || ints[4] == StepCanceled || ints[4] == Terminated || ints[4] == Error;
    if (ints[0] != m->nx || ints[1] != m->nu || ints[2] != m->np || ints[3] != m->ny || !known)
        return fail(c, fmi2Error, "fmi2DeSerializeFMUstate: the serialised sizes or state do not match this FMU");
    FmuState* s = state_to_fill(c, FMUstate, "fmi2DeSerializeFMUstate");
    if (!s) return fmi2Error;
    s->state = (ModelState)ints[4];
    s->params_dirty = ints[5] != 0;
    s->init_valid = ints[6] != 0;
    s->time = times[0];
    s->start_time = times[1];
    memcpy(s->values, b, n_values(m) * sizeof(double)); b += n_values(m) * sizeof(double);
    memcpy(s->warned, b, (size_t)m->ny);
    *FMUstate = s;
    return fmi2OK;
}
