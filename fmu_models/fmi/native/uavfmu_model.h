/* The contract between the shared FMI layer (uavfmu_core.h, fmi2Functions.c, fmi3Functions.c) and one model.
 *
 * In the style of modelica/Reference-FMUs' model.h: the FMI functions and their state machine are written
 * once, by hand, over this contract; each vehicle supplies
 *   - <model>_model.c: CasADi-generated C of its RK4 step, initial state, derivatives and outputs, with the
 *     plain-array entry points below (fmu_models/fmi/codegen.py), and
 *   - <model>_description.c: the table below, generated from the model's variable lists
 *     (fmu_models/fmi/native_build.py). Value reference = index in `variables`.
 * Every global symbol carries the model identifier (uavfmu_config.h: UAVFMU_ID), so the sources of several
 * models link into one program (compile each with -DFMI2_FUNCTION_PREFIX=<id>_ / -DFMI3_FUNCTION_PREFIX=<id>_).
 */
#ifndef UAVFMU_MODEL_H
#define UAVFMU_MODEL_H

#include "uavfmu_config.h"

#ifdef __cplusplus
extern "C" {
#endif

#define UAVFMU_PASTE_(a, b) a##_##b
#define UAVFMU_PASTE(a, b) UAVFMU_PASTE_(a, b)
#define UAVFMU_SYM(name) UAVFMU_PASTE(UAVFMU_ID, name)
#define uavfmu_model UAVFMU_SYM(uavfmu_model)
#define uavfmu_initialize UAVFMU_SYM(uavfmu_initialize)
#define uavfmu_advance UAVFMU_SYM(uavfmu_advance)
#define uavfmu_derivatives UAVFMU_SYM(uavfmu_derivatives)
#define uavfmu_outputs UAVFMU_SYM(uavfmu_outputs)

typedef enum {
    UAVFMU_INPUT = 0, UAVFMU_PARAMETER = 1, UAVFMU_OUTPUT = 2,
    UAVFMU_STATE = 3, UAVFMU_DERIVATIVE = 4, /* Model Exchange: continuous state i and its derivative */
    UAVFMU_TIME = 5                          /* FMI 3.0: the independent variable */
} uavfmu_causality;

typedef struct {
    const char* name;
    const char* unit;
    int causality;      /* uavfmu_causality */
    int index;          /* position in u, p, y or x */
    int boolean;        /* 1: a Boolean output (y > 0.5) */
    double start;
    int has_min, has_max;
    double min, max;
    const char* warning; /* logged once per run when this boolean output turns true, or NULL */
    int tunable;         /* parameters: 1 if a change while simulating takes effect, else fixed */
} uavfmu_variable;

typedef struct {
    const char* name;
    const char* guid;
    int nx, nu, np, ny;
    const uavfmu_variable* variables; /* value reference = index */
    int n_variables;
    const char* const* state_names;
    const char* const* state_units;
    const double* state_limits;       /* |x_i| above this counts as divergence */
    const double* state_nominals;     /* nominal magnitude of each state (Model Exchange) */
    int i_step_internal;              /* index in p of the internal RK4 step (s) */
} uavfmu_model_info;

extern const uavfmu_model_info uavfmu_model;

/* x0, y0 from inputs and parameters; 0 or i+1 when state i is not finite, -1000000 on a CasADi failure */
int uavfmu_initialize(const double* u, const double* p, double* x0, double* y0);

/* advance x by h[0] s in equal RK4 steps of at most h[1] s (at most UAVFMU_MAX_INTERNAL_STEPS: the caller
 * checks first); 0, i+1 when state i left its limit, -(i+1) when output i is not finite, -1000000 on a
 * CasADi failure. x_out and y are written only on success. */
int uavfmu_advance(const double* x, const double* u, const double* p, const double* h, double* x_out, double* y);

/* dx/dt at (x, u, p); 0, or i+1 when derivative i is not finite, -1000000 on a CasADi failure */
int uavfmu_derivatives(const double* x, const double* u, const double* p, double* xdot);

/* outputs at (x, u, p); 0, or -(i+1) when output i is not finite, -1000000 on a CasADi failure */
int uavfmu_outputs(const double* x, const double* u, const double* p, double* y);

#ifdef __cplusplus
}
#endif
#endif
