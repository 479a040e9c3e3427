/* The FMI-version-independent core of the uavfmu native FMUs: one instance type, one state machine
 * (uavfmu_states.h, generated from fmu_models/fmi/statemachine.py), the argument checks, the
 * co-simulation stepper and the Model Exchange evaluations over the model contract (uavfmu_model.h).
 *
 * In the style of modelica/Reference-FMUs (model.c + cosimulation.c): the thin front ends fmi2Functions.c
 * and fmi3Functions.c map their FMI functions onto these; each includes this header once, so everything
 * here is static and only the FMI functions (and the model's prefixed symbols) are global.
 *
 * Every call is checked against the state machine and its arguments before the model sees it; a refused
 * call returns an error status with a logged message and changes nothing. Model failures (a NaN or
 * out-of-range input or parameter, a diverging integration) return an error and move the instance to the
 * Error state, from which Reset starts again; a failed step leaves states, outputs and time as they were.
 */
#ifndef UAVFMU_CORE_H
#define UAVFMU_CORE_H

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "uavfmu_live.h"
#include "uavfmu_model.h"
#include "uavfmu_states.h"

/* The allowed-state mask of an operation for this binary's FMI version (uavfmu_config.h: UAVFMU_FMI_VERSION);
   the front ends' BEGIN and the core's own checks use the same table rows. */
#if UAVFMU_FMI_VERSION == 3
#define UAV_MASK(op) MASK3_##op
#else
#define UAV_MASK(op) MASK_##op
#endif

#define UAV_OK 0
#define UAV_WARNING 1
#define UAV_DISCARD 2
#define UAV_ERROR 3
#define INSTANCE_MAGIC 0x5541564641554d32ULL /* "UAVFMU2" */
#define STATE_MAGIC 0x5541564653544154ULL    /* "UAVFSTAT" */
#define SERIAL_TAG "uavfmu-fmu-state-2"

struct Instance;
/* how a front end hands a message to its importer (FMI 2.0 logger or FMI 3.0 logMessage) */
typedef void (*uavfmu_emit)(struct Instance* c, int status, const char* category, const char* text);

struct FmuState;

typedef struct Instance {
    uint64_t magic;
    const uavfmu_model_info* model;
    char* name;
    int model_exchange;   /* 1: Model Exchange, 0: Co-Simulation */
    uavfmu_emit emit;
    void* env;            /* importer's environment pointer */
    const void* callbacks; /* front end's callback data */
    int logging_on;
    int state;            /* UavfmuState */
    double time;          /* CS: last communication point; ME: current time (s) */
    double start_time;
    int params_dirty;     /* parameters changed since they were last checked */
    int outputs_dirty;    /* y does not belong to the current x, u, p */
    int init_valid;       /* x holds the initial state of the current parameters (initialisation mode) */
    double *x, *x_next, *u, *p, *y, *y_next, *xdot;
    unsigned char* warned; /* per output: warning already logged this run */
    int* kinds;            /* variable indices: inputs, then parameters, then outputs with a warning */
    int n_in, n_par, n_warn;
    int live_slot;           /* its slot in uavfmu_live.h */
    struct FmuState* states; /* every FMU state this instance handed out, freed with it */
    char message[512];
    char why[256];           /* an argument rule's message, before it is logged */
} Instance;

typedef struct FmuState {
    uint64_t magic;
    struct FmuState* next;
    int state;
    double time, start_time;
    int params_dirty, outputs_dirty, init_valid;
    double* values; /* x, u, p, y */
    unsigned char* warned;
} FmuState;

/* ------------------------------------------------------------------ logging */

static int uav_fail(Instance* c, int status, const char* fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->message, sizeof c->message, fmt, ap);
    va_end(ap);
    if (c->emit && (status != UAV_OK || c->logging_on))
        c->emit(c, status, status == UAV_WARNING ? "logStatusWarning"
                           : status == UAV_DISCARD ? "logStatusDiscard" : "logStatusError", c->message);
    return status;
}

/* A function of the other interface (INTERFACE_<op>: 1 Model Exchange, 0 Co-Simulation, -1 both; FMI 2.0.4
   sections 3.2, 4.2; FMI 3.0 sections 3.2.1, 4.2.1) is refused whatever the state: an ME instance never steps,
   a CS instance has no continuous-state vector to hand out. 1 (logged) when refused. */
static int uav_wrong_interface(Instance* c, int interface, const char* fn) {
    if (interface < 0 || c->model_exchange == interface) return 0;
    uav_fail(c, UAV_ERROR, "%s: a %s function, but this instance was instantiated for %s", fn,
             interface ? "Model Exchange" : "Co-Simulation", c->model_exchange ? "Model Exchange" : "Co-Simulation");
    return 1;
}

/* ------------------------------------------------------------------ live instances */

/* The instance if `comp` is a live instance of this binary (uavfmu_live.h: compared by address before anything
   is read through it), else NULL. */
static Instance* uav_ours(const void* comp) {
    if (uav_live_find(comp) < 0) return NULL;
    Instance* c = (Instance*)comp;
    return c->magic == INSTANCE_MAGIC && c->model == &uavfmu_model ? c : NULL;
}

/* The instance, if it is one of ours and fn is allowed in its state, else NULL (a foreign pointer is never
   read or written through; a state error is logged). */
static Instance* uav_enter(void* comp, int mask, const char* fn) {
    Instance* c = uav_ours(comp);
    if (!c) return NULL;
    if (!(c->state & mask)) {
        uav_fail(c, UAV_ERROR, "%s: not allowed in state '%s' (FMI %s state machine)", fn,
                 uavfmu_state_name(c->state), c->model_exchange ? "Model Exchange" : "Co-Simulation");
        return NULL;
    }
    return c;
}

/* ------------------------------------------------------------------ instance */

static void uav_set_starts(Instance* c) {
    const uavfmu_model_info* m = c->model;
    for (int i = 0; i < m->n_variables; ++i) {
        const uavfmu_variable* v = &m->variables[i];
        if (v->causality == UAVFMU_INPUT) c->u[v->index] = v->start;
        else if (v->causality == UAVFMU_PARAMETER) c->p[v->index] = v->start;
    }
    memset(c->x, 0, sizeof(double) * (size_t)(m->nx + 1));
    memset(c->y, 0, sizeof(double) * (size_t)(m->ny + 1));
    memset(c->warned, 0, (size_t)m->ny + 1);
    c->time = c->start_time = 0.0;
    c->params_dirty = c->outputs_dirty = 1;
    c->init_valid = 0;
}

static void uav_free_state(FmuState* s) {
    if (!s) return;
    s->magic = 0;
    free(s->values);
    free(s->warned);
    free(s);
}

/* Frees the memory of an instance (not or no longer live) (NULL: nothing). */
static void uav_release(Instance* c) {
    if (!c) return;
    free(c->x);
    free(c->warned);
    free(c->kinds);
    free(c->name);
    free(c);
}

/* Frees a live instance (the caller has it from uav_ours) with every FMU state it handed out. */
static void uav_free(Instance* c) {
    uav_live_remove(c->live_slot, c);
    FmuState* s = c->states;
    while (s) {
        FmuState* n = s->next;
        uav_free_state(s);
        s = n;
    }
    c->magic = 0;
    uav_release(c);
}

/* A new instance in state Instantiated, or NULL after logging why through `tmp` (a stack instance). */
static Instance* uav_new(Instance* tmp, const char* name, const char* token, int model_exchange) {
    const uavfmu_model_info* m = &uavfmu_model;
    tmp->name = (char*)(name && name[0] ? name : "?");
    tmp->model_exchange = model_exchange;
    if (!uavfmu_rule_name(tmp->why, sizeof tmp->why, name)) {
        uav_fail(tmp, UAV_ERROR, "instantiate: %s", tmp->why);
        return NULL;
    }
    if (!token || strcmp(token, m->guid) != 0) {
        uav_fail(tmp, UAV_ERROR, "instantiate: GUID/instantiationToken %s does not match this binary's %s",
                 token ? token : "(null)", m->guid);
        return NULL;
    }
    Instance* c = (Instance*)calloc(1, sizeof(Instance));
    size_t n = (size_t)(3 * m->nx + m->nu + m->np + 2 * m->ny) + 8;
    if (c) {
        c->x = (double*)calloc(n, sizeof(double));
        c->warned = (unsigned char*)calloc((size_t)m->ny + 1, 1);
        c->kinds = (int*)calloc((size_t)m->n_variables + 1, sizeof(int));
        c->name = (char*)malloc(strlen(name) + 1);
    }
    if (!c || !c->x || !c->warned || !c->kinds || !c->name) {
        uav_release(c);
        uav_fail(tmp, UAV_ERROR, "instantiate: out of memory");
        return NULL;
    }
    strcpy(c->name, name);
    c->x_next = c->x + m->nx + 1;
    c->xdot = c->x_next + m->nx + 1;
    c->u = c->xdot + m->nx + 1;
    c->p = c->u + m->nu + 1;
    c->y = c->p + m->np + 1;
    c->y_next = c->y + m->ny + 1;
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
    c->model_exchange = model_exchange;
    c->emit = tmp->emit;
    c->env = tmp->env;
    c->callbacks = tmp->callbacks;
    c->logging_on = tmp->logging_on;
    c->state = Instantiated;
    uav_set_starts(c);
    c->live_slot = uav_live_add(c);
    if (c->live_slot < 0) {
        uav_fail(tmp, UAV_ERROR, "instantiate: %d instances of %s are live already, the most one binary holds",
                 UAV_MAX_INSTANCES, m->name);
        c->magic = 0;
        uav_release(c);
        return NULL;
    }
    return c;
}

static int uav_setup(Instance* c, int tol_defined, double tol, double start, int stop_defined, double stop,
                     const char* fn) {
    if (!uavfmu_rule_setup(c->why, sizeof c->why, tol_defined, tol, start, stop_defined, stop))
        return uav_fail(c, UAV_ERROR, "%s: %s", fn, c->why);
    c->start_time = c->time = start;
    return UAV_OK;
}

/* Python's repr of a float (shortest round-trip, "3100.0", "nan"), so messages read as the pythonfmu backend's */
static const char* uav_num(double v, char* buf, size_t n) {
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

/* 0 if every input (or parameter) is finite and inside [min, max], else 1 after logging which is not */
static int uav_check_values(Instance* c, int causality, const char* fn, double t) {
    const uavfmu_model_info* m = c->model;
    const double* arr = causality == UAVFMU_INPUT ? c->u : c->p;
    const int* list = causality == UAVFMU_INPUT ? c->kinds : c->kinds + c->n_in;
    int n = causality == UAVFMU_INPUT ? c->n_in : c->n_par;
    for (int k = 0; k < n; ++k) {
        const uavfmu_variable* v = &m->variables[list[k]];
        double val = arr[v->index];
        if (val != val || (v->has_min && val < v->min) || (v->has_max && val > v->max) || isinf(val)) {
            char a[40], b[40], d[40], when[96];
            /* the time is formatted only here, on failure: doStep's hot path formats nothing */
            if (fn && t == t) snprintf(when, sizeof when, "%s at t = %g s", fn, t);
            else if (fn) snprintf(when, sizeof when, "%s", fn);  /* t = NaN: no time (initialisation) */
            else snprintf(when, sizeof when, "t = %g s", t);
            uav_fail(c, UAV_ERROR, "%s: %s %s = %s is outside its allowed range [%s, %s]", when,
                     causality == UAVFMU_INPUT ? "input" : "parameter", v->name, uav_num(val, a, sizeof a),
                     v->has_min ? uav_num(v->min, b, sizeof b) : "None",
                     v->has_max ? uav_num(v->max, d, sizeof d) : "None");
            return 1;
        }
    }
    return 0;
}

/* inputs always, parameters when changed: 0 if usable, else 1 (logged, instance in the Error state) */
static int uav_check_inputs(Instance* c, const char* fn, double t) {
    if (uav_check_values(c, UAVFMU_INPUT, fn, t) || (c->params_dirty && uav_check_values(c, UAVFMU_PARAMETER, fn, t))) {
        c->state = Error;
        return 1;
    }
    c->params_dirty = 0;
    return 0;
}

static const char* uav_diverged(Instance* c, int status, const char* what, char* buf, size_t n) {
    const uavfmu_model_info* m = c->model;
    if (status > 0 && status <= m->nx)
        snprintf(buf, n, "%s %s left [-%g, %g] %s or became NaN", what, m->state_names[status - 1],
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

/* x and y from the current inputs and parameters (initialisation) */
static int uav_initialize(Instance* c, const char* when) {
    char why[256];
    if (uav_check_values(c, UAVFMU_PARAMETER, when, NAN)) return UAV_ERROR;
    int s = uavfmu_initialize(c->u, c->p, c->x, c->y);
    if (s)
        return uav_fail(c, UAV_ERROR, "%s: the initial state is not finite (%s)", when,
                        uav_diverged(c, s, "state", why, sizeof why));
    c->params_dirty = 0;
    c->outputs_dirty = 0;
    c->init_valid = 1;
    return UAV_OK;
}

static int uav_exit_init(Instance* c) {
    memset(c->warned, 0, (size_t)c->model->ny + 1);
    if (uav_initialize(c, "initialisation") != UAV_OK) {
        c->state = Error;
        return UAV_ERROR;
    }
    c->init_valid = 0;
    c->time = c->start_time;
    c->state = c->model_exchange ? EventMode : StepComplete;
    return UAV_OK;
}

static void uav_reset(Instance* c) {
    uav_set_starts(c);
    c->state = Instantiated;
}

/* warnings of the boolean outputs that just turned true, once per run */
static int uav_warn(Instance* c) {
    int status = UAV_OK;
    const uavfmu_model_info* m = c->model;
    for (int k = c->n_in + c->n_par; k < c->n_in + c->n_par + c->n_warn; ++k) {
        const uavfmu_variable* v = &m->variables[c->kinds[k]];
        if (c->y[v->index] > 0.5 && !c->warned[v->index]) {
            c->warned[v->index] = 1;
            status = uav_fail(c, UAV_WARNING, "t = %g s: %s (logged once per run)", c->time, v->warning);
        }
    }
    return status == UAV_WARNING ? UAV_OK : status; /* logged; the call itself succeeded */
}

/* initialisation mode: x and y are the initial state of the current inputs and parameters (computed when they
   changed; a failure moves the instance to the Error state); any other state: nothing to do */
static int uav_initial_state_ready(Instance* c, const char* fn) {
    if (c->state != InitializationMode || (c->init_valid && !c->params_dirty && !c->outputs_dirty)) return UAV_OK;
    if (uav_initialize(c, fn) == UAV_OK) return UAV_OK;
    c->state = Error;
    return UAV_ERROR;
}

/* y for the current x, u, p: initialisation mode computes the initial state first */
static int uav_outputs_ready(Instance* c, const char* fn) {
    if (c->state == InitializationMode) return uav_initial_state_ready(c, fn);
    if (!c->outputs_dirty || c->state == Error) return UAV_OK;
    char why[256];
    if (uav_check_inputs(c, fn, c->time)) return UAV_ERROR;
    int s = uavfmu_outputs(c->x, c->u, c->p, c->y_next);
    if (s) {
        c->state = Error;
        return uav_fail(c, UAV_ERROR, "%s at t = %g s: %s", fn, c->time, uav_diverged(c, s, "state", why, sizeof why));
    }
    memcpy(c->y, c->y_next, sizeof(double) * (size_t)c->model->ny);
    c->outputs_dirty = 0;
    return UAV_OK;
}

/* ------------------------------------------------------------------ get / set */

static const uavfmu_variable* uav_lookup(Instance* c, unsigned vr, const char* fn, int want_boolean) {
    const uavfmu_model_info* m = c->model;
    if (vr >= (unsigned)m->n_variables) {
        uav_fail(c, UAV_ERROR, "%s: unknown value reference %u (this FMU has 0..%d)", fn, vr, m->n_variables - 1);
        return NULL;
    }
    const uavfmu_variable* v = &m->variables[vr];
    if (v->boolean != want_boolean) {
        uav_fail(c, UAV_ERROR, "%s: value reference %u (%s) is a %s variable", fn, vr, v->name,
                 v->boolean ? "Boolean" : "Real");
        return NULL;
    }
    return v;
}

static double* uav_slot(Instance* c, const uavfmu_variable* v) {
    switch (v->causality) {
    case UAVFMU_INPUT: return &c->u[v->index];
    case UAVFMU_PARAMETER: return &c->p[v->index];
    case UAVFMU_STATE: return &c->x[v->index];
    case UAVFMU_DERIVATIVE: return &c->xdot[v->index];
    case UAVFMU_TIME: return &c->time;
    default: return &c->y[v->index];
    }
}

static int uav_get_derivatives(Instance* c, double* xdot, size_t n, const char* fn);

/* Real (boolean = 0) or Boolean (boolean = 1, as doubles) values of vr[0..n) into out */
static int uav_get(Instance* c, const unsigned* vr, size_t n, double* out, int boolean, const char* fn) {
    if (n == 0) return UAV_OK;
    if (!vr || !out) return uav_fail(c, UAV_ERROR, "%s: vr or value is NULL with nvr = %zu", fn, n);
    int need_outputs = 0, need_derivatives = 0;
    for (size_t i = 0; i < n; ++i) {
        const uavfmu_variable* v = uav_lookup(c, vr[i], fn, boolean);
        if (!v) return UAV_ERROR;
        int start = v->causality == UAVFMU_INPUT || v->causality == UAVFMU_PARAMETER;
        if (!(c->state & (start ? UAV_MASK(GetStart) : UAV_MASK(GetValue))))
            return uav_fail(c, UAV_ERROR, "%s: %s cannot be read in state '%s'%s", fn, v->name,
                            uavfmu_state_name(c->state), c->state == Instantiated ? " (it has no start value; before "
                            "initialization mode only inputs and parameters can be read)" : "");
        need_outputs |= v->causality == UAVFMU_OUTPUT;
        need_derivatives |= v->causality == UAVFMU_DERIVATIVE;
    }
    if (need_outputs && uav_outputs_ready(c, fn) != UAV_OK) return UAV_ERROR;
    if (need_derivatives && uav_get_derivatives(c, c->xdot, (size_t)c->model->nx, fn) != UAV_OK) return UAV_ERROR;
    for (size_t i = 0; i < n; ++i) out[i] = *uav_slot(c, &c->model->variables[vr[i]]);
    return UAV_OK;
}

/* check every value reference first (a refused call changes nothing), then set */
static int uav_set_real(Instance* c, const unsigned* vr, size_t n, const double* value, const char* fn) {
    if (n == 0) return UAV_OK;
    if (!vr || !value) return uav_fail(c, UAV_ERROR, "%s: vr or value is NULL with nvr = %zu", fn, n);
    for (size_t i = 0; i < n; ++i) {
        const uavfmu_variable* v = uav_lookup(c, vr[i], fn, 0);
        if (!v) return UAV_ERROR;
        if (v->causality != UAVFMU_INPUT && v->causality != UAVFMU_PARAMETER)
            return uav_fail(c, UAV_ERROR, "%s: %s is %s and cannot be set", fn, v->name,
                            v->causality == UAVFMU_OUTPUT ? "an output" : v->causality == UAVFMU_TIME
                            ? "the independent variable" : "a calculated local variable (Model Exchange: use "
                            "SetContinuousStates)");
        int mask = v->causality == UAVFMU_INPUT ? UAV_MASK(SetInput)
                   : v->tunable ? UAV_MASK(SetTunable) : UAV_MASK(SetFixed);
        if (!(c->state & mask))
            return uav_fail(c, UAV_ERROR, "%s: %s (%s) cannot be set in state '%s'", fn, v->name,
                            v->causality == UAVFMU_INPUT ? "input" : v->tunable ? "tunable parameter"
                                                                                 : "fixed parameter",
                            uavfmu_state_name(c->state));
    }
    for (size_t i = 0; i < n; ++i) {
        const uavfmu_variable* v = &c->model->variables[vr[i]];
        if (v->causality == UAVFMU_PARAMETER) c->params_dirty = 1;
        *uav_slot(c, v) = value[i];
    }
    c->outputs_dirty = 1;
    return UAV_OK;
}

static int uav_boolean_output(Instance* c, const unsigned* vr, size_t n, const char* fn) {
    if (n == 0) return UAV_OK;
    if (!vr) return uav_fail(c, UAV_ERROR, "%s: vr is NULL with nvr = %zu", fn, n);
    const uavfmu_variable* v = uav_lookup(c, vr[0], fn, 1);
    if (!v) return UAV_ERROR;
    return uav_fail(c, UAV_ERROR, "%s: %s is an output and cannot be set", fn, v->name);
}

static int uav_no_such_type(Instance* c, const unsigned* vr, size_t n, const char* fn) {
    if (n == 0) return UAV_OK;
    if (!vr) return uav_fail(c, UAV_ERROR, "%s: vr is NULL with nvr = %zu", fn, n);
    if (vr[0] < (unsigned)c->model->n_variables)
        return uav_fail(c, UAV_ERROR, "%s: value reference %u (%s) is a %s variable; this FMU has no variable of "
                        "this type", fn, vr[0], c->model->variables[vr[0]].name,
                        c->model->variables[vr[0]].boolean ? "Boolean" : "Real");
    return uav_fail(c, UAV_ERROR, "%s: unknown value reference %u", fn, vr[0]);
}

/* ------------------------------------------------------------------ Co-Simulation step */

static int uav_do_step(Instance* c, double t, double h, const char* fn) {
    const uavfmu_model_info* m = c->model;
    double dt = c->p[m->i_step_internal];
    if (!uavfmu_rule_step(c->why, sizeof c->why, t, h, c->time) ||
        !uavfmu_rule_internal_steps(c->why, sizeof c->why, h, dt))
        return uav_fail(c, UAV_ERROR, "%s: %s", fn, c->why);
    if (uav_check_inputs(c, NULL, t)) return UAV_ERROR;
    double hh[2] = {h, dt};
    int s = uavfmu_advance(c->x, c->u, c->p, hh, c->x_next, c->y_next);
    if (s) {
        char why[256];
        c->state = Error;
        return uav_fail(c, UAV_ERROR, "t = %g s: integration diverged: %s", t,
                        uav_diverged(c, s, "state", why, sizeof why));
    }
    memcpy(c->x, c->x_next, sizeof(double) * (size_t)m->nx);
    memcpy(c->y, c->y_next, sizeof(double) * (size_t)m->ny);
    c->outputs_dirty = 0;
    c->time = t + h;
    return uav_warn(c);
}

/* ------------------------------------------------------------------ Model Exchange */

static int uav_set_time(Instance* c, double t, const char* fn) {
    if (!uavfmu_rule_time(c->why, sizeof c->why, t)) return uav_fail(c, UAV_ERROR, "%s: %s", fn, c->why);
    c->time = t;
    return UAV_OK;
}

static int uav_check_nx(Instance* c, const void* array, size_t n, const char* fn) {
    if (!array && n) return uav_fail(c, UAV_ERROR, "%s: the array is NULL", fn);
    if (n != (size_t)c->model->nx)
        return uav_fail(c, UAV_ERROR, "%s: %zu values, this model has %d continuous states", fn, n, c->model->nx);
    return UAV_OK;
}

static int uav_set_states(Instance* c, const double* x, size_t n, const char* fn) {
    if (uav_check_nx(c, x, n, fn)) return UAV_ERROR;
    for (size_t i = 0; i < n; ++i)
        if (!isfinite(x[i]))
            return uav_fail(c, UAV_ERROR, "%s: state %s = %g is not finite", fn, c->model->state_names[i], x[i]);
    memcpy(c->x, x, sizeof(double) * n);
    c->outputs_dirty = 1;
    return UAV_OK;
}

static int uav_get_states(Instance* c, double* x, size_t n, const char* fn) {
    if (uav_check_nx(c, x, n, fn) || uav_initial_state_ready(c, fn)) return UAV_ERROR;
    memcpy(x, c->x, sizeof(double) * n);
    return UAV_OK;
}

static int uav_get_derivatives(Instance* c, double* xdot, size_t n, const char* fn) {
    if (uav_check_nx(c, xdot, n, fn) || uav_initial_state_ready(c, fn)) return UAV_ERROR;
    char why[256];
    if (c->state != Error && uav_check_inputs(c, fn, c->time)) return UAV_ERROR;
    int s = uavfmu_derivatives(c->x, c->u, c->p, c->xdot);
    if (s) {
        c->state = Error;
        return uav_fail(c, UAV_ERROR, "%s at t = %g s: %s", fn, c->time,
                        uav_diverged(c, s, "the derivative of state", why, sizeof why));
    }
    memmove(xdot, c->xdot, sizeof(double) * n);
    return UAV_OK;
}

static int uav_get_nominals(Instance* c, double* x, size_t n, const char* fn) {
    if (uav_check_nx(c, x, n, fn)) return UAV_ERROR;
    memcpy(x, c->model->state_nominals, sizeof(double) * n);
    return UAV_OK;
}

/* after an accepted integrator step: the states must stay inside their limits; warnings logged once */
static int uav_completed_integrator_step(Instance* c, const char* fn) {
    char why[256];
    for (int i = 0; i < c->model->nx; ++i)
        if (!(fabs(c->x[i]) <= c->model->state_limits[i])) {
            c->state = Error;
            return uav_fail(c, UAV_ERROR, "%s at t = %g s: integration diverged: %s", fn, c->time,
                            uav_diverged(c, i + 1, "state", why, sizeof why));
        }
    if (c->n_warn && uav_outputs_ready(c, fn) != UAV_OK) return UAV_ERROR;
    return uav_warn(c);
}

/* ------------------------------------------------------------------ FMU state */

static size_t uav_n_values(const uavfmu_model_info* m) { return (size_t)(m->nx + m->nu + m->np + m->ny); }

/* the state if this instance handed it out (compared by address: a foreign pointer is never read) */
static FmuState* uav_owned(Instance* c, const void* state, const char* fn) {
    for (FmuState* s = c->states; s; s = s->next)
        if ((const void*)s == state) return s;
    uav_fail(c, UAV_ERROR, "%s: the FMU state %p was not created by this instance (or was freed)", fn, state);
    return NULL;
}

/* the FMU state a call fills: *slot when this instance handed it out, else (NULL) a new one; NULL if refused */
static FmuState* uav_state_to_fill(Instance* c, void* const* slot, const char* fn) {
    if (*slot) return uav_owned(c, *slot, fn);
    FmuState* s = (FmuState*)calloc(1, sizeof(FmuState));
    if (s) {
        s->values = (double*)calloc(uav_n_values(c->model) + 1, sizeof(double));
        s->warned = (unsigned char*)calloc((size_t)c->model->ny + 1, 1);
    }
    if (!s || !s->values || !s->warned) {
        uav_free_state(s);
        uav_fail(c, UAV_ERROR, "%s: out of memory", fn);
        return NULL;
    }
    s->magic = STATE_MAGIC;
    s->next = c->states;
    c->states = s;
    return s;
}

static void uav_copy_values(const uavfmu_model_info* m, double* dst, double* x, double* u, double* p, double* y,
                            int to_state) {
    double* parts[4] = {x, u, p, y};
    int sizes[4] = {m->nx, m->nu, m->np, m->ny};
    for (int k = 0; k < 4; ++k) {
        if (to_state) memcpy(dst, parts[k], sizeof(double) * (size_t)sizes[k]);
        else memcpy(parts[k], dst, sizeof(double) * (size_t)sizes[k]);
        dst += sizes[k];
    }
}

static int uav_get_state(Instance* c, void** slot, const char* fn) {
    if (!slot) return uav_fail(c, UAV_ERROR, "%s: FMUstate is NULL", fn);
    FmuState* s = uav_state_to_fill(c, slot, fn);
    if (!s) return UAV_ERROR;
    uav_copy_values(c->model, s->values, c->x, c->u, c->p, c->y, 1);
    memcpy(s->warned, c->warned, (size_t)c->model->ny);
    s->state = c->state;
    s->time = c->time;
    s->start_time = c->start_time;
    s->params_dirty = c->params_dirty;
    s->outputs_dirty = c->outputs_dirty;
    s->init_valid = c->init_valid;
    *slot = s;
    return UAV_OK;
}

static int uav_set_state(Instance* c, const void* state, const char* fn) {
    FmuState* s = uav_owned(c, state, fn);
    if (!s) return UAV_ERROR;
    uav_copy_values(c->model, s->values, c->x, c->u, c->p, c->y, 0);
    memcpy(c->warned, s->warned, (size_t)c->model->ny);
    c->state = s->state;
    c->time = s->time;
    c->start_time = s->start_time;
    c->params_dirty = 1; /* re-checked before the next step, as after any parameter change */
    c->outputs_dirty = s->outputs_dirty;
    c->init_valid = s->init_valid;
    return UAV_OK;
}

static int uav_free_fmu_state(Instance* c, void** slot, const char* fn) {
    if (!slot) return uav_fail(c, UAV_ERROR, "%s: FMUstate is NULL", fn);
    if (!*slot) return UAV_OK;
    FmuState* s = uav_owned(c, *slot, fn);
    if (!s) return UAV_ERROR;
    FmuState** link = &c->states;
    while (*link != s) link = &(*link)->next;
    *link = s->next;
    uav_free_state(s);
    *slot = NULL;
    return UAV_OK;
}

/* serialised layout: tag, guid, 8 int32 (sizes, state, flags), 2 doubles (times), values, warned, then a
   64-bit FNV-1a checksum of all that (a damaged byte anywhere is refused, as by the pythonfmu shim) */
static size_t uav_serial_size(const uavfmu_model_info* m) {
    return sizeof SERIAL_TAG + strlen(m->guid) + 1 + 8 * sizeof(int32_t) + (2 + uav_n_values(m)) * sizeof(double) +
           (size_t)m->ny + sizeof(uint64_t);
}

static uint64_t uav_fnv(const unsigned char* b, size_t n) {
    uint64_t h = 1469598103934665603ULL;
    for (size_t i = 0; i < n; ++i) { h ^= b[i]; h *= 1099511628211ULL; }
    return h;
}

static int uav_serialized_size(Instance* c, const void* state, size_t* size, const char* fn) {
    if (!size) return uav_fail(c, UAV_ERROR, "%s: size is NULL", fn);
    if (!uav_owned(c, state, fn)) return UAV_ERROR;
    *size = uav_serial_size(c->model);
    return UAV_OK;
}

static int uav_serialize(Instance* c, const void* state, unsigned char* b, size_t size, const char* fn) {
    FmuState* s = uav_owned(c, state, fn);
    if (!s) return UAV_ERROR;
    const uavfmu_model_info* m = c->model;
    if (!b) return uav_fail(c, UAV_ERROR, "%s: serializedState is NULL", fn);
    if (size < uav_serial_size(m))
        return uav_fail(c, UAV_ERROR, "%s: buffer of %zu bytes is smaller than the %zu needed", fn, size,
                        uav_serial_size(m));
    int32_t ints[8] = {m->nx, m->nu, m->np, m->ny, (int32_t)s->state, s->params_dirty, s->init_valid,
                       s->outputs_dirty};
    double times[2] = {s->time, s->start_time};
    unsigned char* start = b;
    memcpy(b, SERIAL_TAG, sizeof SERIAL_TAG); b += sizeof SERIAL_TAG;
    memcpy(b, m->guid, strlen(m->guid) + 1); b += strlen(m->guid) + 1;
    memcpy(b, ints, sizeof ints); b += sizeof ints;
    memcpy(b, times, sizeof times); b += sizeof times;
    memcpy(b, s->values, uav_n_values(m) * sizeof(double)); b += uav_n_values(m) * sizeof(double);
    memcpy(b, s->warned, (size_t)m->ny); b += m->ny;
    uint64_t sum = uav_fnv(start, (size_t)(b - start));
    memcpy(b, &sum, sizeof sum);
    return UAV_OK;
}

static int uav_deserialize(Instance* c, const unsigned char* b, size_t size, void** slot, const char* fn) {
    const uavfmu_model_info* m = c->model;
    if (!b || !slot) return uav_fail(c, UAV_ERROR, "%s: NULL argument", fn);
    size_t glen = strlen(m->guid) + 1;
    uint64_t sum = 0;
    if (size == uav_serial_size(m)) memcpy(&sum, b + size - sizeof sum, sizeof sum);
    if (size != uav_serial_size(m) || memcmp(b, SERIAL_TAG, sizeof SERIAL_TAG) ||
        memcmp(b + sizeof SERIAL_TAG, m->guid, glen) || sum != uav_fnv(b, size - sizeof sum))
        return uav_fail(c, UAV_ERROR, "%s: %zu bytes are not a serialised state of this FMU (%s)", fn, size, m->guid);
    b += sizeof SERIAL_TAG + glen;
    int32_t ints[8];
    double times[2];
    memcpy(ints, b, sizeof ints); b += sizeof ints;
    memcpy(times, b, sizeof times); b += sizeof times;
    int known = ints[4] == Instantiated || ints[4] == InitializationMode || ints[4] == StepComplete ||
                ints[4] == EventMode || ints[4] == ContinuousTimeMode || ints[4] == StepFailed ||
                ints[4] == StepCanceled || ints[4] == Terminated || ints[4] == Error;
    int mode_ok = !(ints[4] & (c->model_exchange ? (StepComplete | StepFailed | StepCanceled)
                                                 : (EventMode | ContinuousTimeMode)));
    if (ints[0] != m->nx || ints[1] != m->nu || ints[2] != m->np || ints[3] != m->ny || !known || !mode_ok ||
        !isfinite(times[0]) || !isfinite(times[1]))
        return uav_fail(c, UAV_ERROR, "%s: the serialised sizes, state or times do not match this FMU", fn);
    FmuState* s = uav_state_to_fill(c, slot, fn);
    if (!s) return UAV_ERROR;
    s->state = ints[4];
    s->params_dirty = ints[5] != 0;
    s->init_valid = ints[6] != 0;
    s->outputs_dirty = ints[7] != 0;
    s->time = times[0];
    s->start_time = times[1];
    memcpy(s->values, b, uav_n_values(m) * sizeof(double)); b += uav_n_values(m) * sizeof(double);
    memcpy(s->warned, b, (size_t)m->ny);
    *slot = s;
    return UAV_OK;
}

#endif
