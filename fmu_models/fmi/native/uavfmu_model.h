/* The contract between the generic FMI 2.0 Co-Simulation layer (fmi2_cs.c) and one vehicle model.
 *
 * In the style of modelica/Reference-FMUs' model.h: the FMI functions and their state machine are
 * written once, by hand, in fmi2_cs.c; each vehicle supplies
 *   - <model>_model.c: CasADi-generated C of its RK4 step and initial state, with the plain-array
 *     entry points uavfmu_initialize / uavfmu_advance (fmu_models/fmi/codegen.py), and
 *   - <model>_description.c: the table below, generated from the model's variable lists
 *     (fmu_models/fmi/native_build.py). Value reference = index in `variables`.
 */
#ifndef UAVFMU_MODEL_H
#define UAVFMU_MODEL_H

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { UAVFMU_INPUT = 0, UAVFMU_PARAMETER = 1, UAVFMU_OUTPUT = 2 } uavfmu_causality;

typedef struct {
    const char* name;
    const char* unit;
    int causality;      /* uavfmu_causality */
    int index;          /* position in u, p or y */
    int boolean;        /* 1: an fmi2Boolean output (y > 0.5) */
    double start;
    int has_min, has_max;
    double min, max;
    const char* warning; /* logged once per run when this boolean output turns true, or NULL */
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
    int i_step_internal;              /* index in p of the internal RK4 step (s) */
} uavfmu_model_info;

extern const uavfmu_model_info uavfmu_model;

/* x0, y0 from inputs and parameters; 0 or i+1 when state i is not finite, -1000000 on a CasADi failure */
int uavfmu_initialize(const double* u, const double* p, double* x0, double* y0);

/* advance x by h[0] s in equal RK4 steps of at most h[1] s; 0, i+1 when state i left its limit,
 * -(i+1) when output i is not finite, -1000000 on a CasADi failure */
int uavfmu_advance(const double* x, const double* u, const double* p, const double* h, double* x_out, double* y);

#ifdef __cplusplus
}
#endif
#endif
