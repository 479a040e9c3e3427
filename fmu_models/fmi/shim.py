"""A guarding FMI 2.0 binary in front of pythonfmu's: the FMI state machine and every argument are checked
before pythonfmu sees a call, so a wrong call is an fmi2Error with a logged message, never a crash.

``<id>.so`` (this shim) loads pythonfmu's library (shipped beside it as ``<id>_pythonfmu.so``) and forwards
the calls that pass its checks. Why a C layer, and what it protects against in pythonfmu 0.7's export library
(``PySlaveInstance.cpp``, ``fmi2.cpp``; all reproduced here, see tests/fmu_models/fmi/test_fmi_sequences.py):

* Any Python exception in the slave (a bad value reference, a value of the wrong type, setting an output, a
  foreign FMU state) makes pythonfmu return fmi2Fatal after *releasing the slave's Python objects* in
  ``handle_py_exception``; ``fmi2FreeInstance`` then releases them a second time (``cleanPyObject`` runs again
  in the destructor) and ``fmi2Reset`` re-releases the dead instance: a double ``Py_DECREF`` of the slave
  class and instance, i.e. heap corruption and a segfault two calls later. So the shim refuses every call that
  could raise (value references and types against the modelDescription table compiled in, causality of set
  variables, NULL arrays, the FMI 2.0 state machine, ``doStep`` time continuity, FMU-state ownership and
  serialised-state integrity). If pythonfmu still reports fmi2Fatal, the instance is quarantined: every call
  but ``fmi2FreeInstance`` returns fmi2Error, and free does not hand the released instance back to
  pythonfmu (a deliberate leak of one broken instance instead of a double free).
* pythonfmu keeps its interpreter guard in a static ``std::shared_ptr`` *and* resets it from an
  ``__attribute__((destructor))``. At ``exit()`` the C++ static destructor runs first (it is an atexit
  handler), then ``_dl_fini`` runs the library destructor on the destroyed ``shared_ptr``: a decrement in
  freed memory (the malloc chunk's list pointer when the block sits in a bin), and a virtual call plus a
  second ``delete`` when the stale count reads 1. That is the intermittent ``corrupted double-linked list``
  abort at the exit of a process that loaded a pythonfmu FMU. The shim registers an exit handler
  *after* loading pythonfmu's library (exit handlers run in reverse order of registration, so it runs
  before pythonfmu's static destructor) that releases the guard through pythonfmu's own
  ``finalizePythonInterpreter``; both later releases then see an empty pointer.
* pythonfmu returns fmi2Discard when ``do_step`` returns False; the FMI 2.0 standard asks for fmi2Error when a
  step cannot be computed (NaN input, divergence) but the instance may be reset or freed: mapped here.
* One state machine with the native layer: the allowed-state masks and argument rules come from the same
  generated ``uavfmu_states.h`` (``fmu_models/fmi/statemachine.py``), so both backends answer every call alike
  (tests/fmu_models/fmi/test_fmi_sequences.py requires identical statuses). The slave never raises into pythonfmu:
  it reports a model failure (a refused parameter at initialisation, an output recomputed from a refused input)
  by logging an error, which the shim turns into fmi2Error and the Error state, as the native layer does. The
  shim tracks ``step_internal_s`` from the values set, to refuse a step needing too many internal steps before
  pythonfmu sees it, and derives the resource location from its own path when the importer passes NULL.

pythonfmu forwards log messages only when logging is on, so the shim turns it on: the slave logs nothing but
warnings and errors, which FMI 2.0 expects to reach the importer whatever its debug-logging setting.
"""

from __future__ import annotations

import json
from pathlib import Path
from xml.etree import ElementTree as ET

import fmpy

from fmu_models.fmi import statemachine
from fmu_models.fmi.codegen import compile_library

HEADERS = Path(fmpy.__file__).parent / "c-code"

#: (value reference, type letter R/I/B/S, settable: 0 never (output), 1 fixed parameter, 2 tunable parameter, 3 input,
#: name, start value or None)
VarRow = tuple[int, str, int, str, float | None]
#: the parameter the shim tracks to refuse a step needing too many internal steps (as the native layer)
INTERNAL_STEP = "step_internal_s"

_TYPES = {"Real": "R", "Integer": "I", "Enumeration": "I", "Boolean": "B", "String": "S"}


def variable_table(model_description: bytes) -> list[VarRow]:
    """The shim's table of every ScalarVariable of a modelDescription.xml, sorted by value reference."""
    root = ET.fromstring(model_description)
    rows: list[VarRow] = []
    for sv in root.iter("ScalarVariable"):
        kind = next((_TYPES[c.tag] for c in sv if c.tag in _TYPES), None)
        if kind is None:
            continue
        causality = sv.get("causality", "local")
        variability = sv.get("variability", "continuous")
        settable = 0
        if causality == "input":
            settable = 3
        elif causality == "parameter":
            settable = 2 if variability == "tunable" else 1
        start = next((c.get("start") for c in sv if c.tag in _TYPES and c.get("start") is not None), None)
        rows.append((int(sv.get("valueReference")), kind, settable, sv.get("name", ""),
                     float(start) if start is not None and kind == "R" else None))
    return sorted(rows)


C_CORE = r"""
/* Generated by uavfmu (fmu_models/fmi/shim.py): FMI 2.0 state machine and argument checks in front of
   pythonfmu's library, which it loads from the same folder. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"
#include "uavfmu_states.h" /* the one state machine table (fmu_models/fmi/statemachine.py) */
#include "uavfmu_live.h"   /* the live handles, as the native layer keeps them */

typedef struct { fmi2ValueReference vr; char type; char settable; const char* name; } VarInfo;
@TABLE@

/* the pythonfmu slave is Co-Simulation only: these are the states it can be in */
#define S_INSTANTIATED Instantiated
#define S_INIT InitializationMode
#define S_STEPPING StepComplete
#define S_TERMINATED Terminated
#define S_ERROR Error
#define S_FATAL Fatal
#define INST_MAGIC 0x7561766675696e73ULL
#define STATE_MAGIC 0x7561766673746174ULL
#define MAX_NVR 1000000u
static const char SER_MAGIC[8] = {'U', 'A', 'V', 'F', 'M', 'U', 'S', '1'};
/* magic, model key, checksum (of everything after it), time, machine state, internal step */
enum { SER_HEADER = 8 + 8 + 8 + 8 + 8 + 8 };

typedef struct State { uint64_t magic; struct Inst* owner; fmi2FMUstate real; double time; int mstate;
                       struct State* next; double dt; } State;
/* A pythonfmu instance with the callbacks the shim gave it (its logger forwards to the current owner). */
typedef struct Slot { fmi2Component real; struct Inst* owner; fmi2CallbackFunctions cb; char key[4096];
                      struct Slot* next; } Slot;
/* dt: the model's internal step (s), tracked from SetReal so a step needing too many is refused up front */
typedef struct Inst { uint64_t magic; int live_slot; fmi2Component real; Slot* slot; int state; double time;
                      fmi2CallbackFunctions cb; char name[128]; State* states; int logged_error; double dt; } Inst;

static Slot* pool = NULL;  /* freed instances kept for reuse: pythonfmu leaks ~1 KB per fmi2Instantiate */
static int pooled = 0;
#define POOL_MAX 4
static void* real_lib = NULL;
static char load_error[1024] = "";

static void on_unload(void) {
  /* Runs when this library is unloaded (dlclose) or at exit, before pythonfmu's static destructors (see
     fmu_models/fmi/shim.py): free the pooled instances while Python is alive, release pythonfmu's interpreter
     guard through its own function, and unload pythonfmu when nothing of it is live. */
  int (*alive)(void) = (int (*)(void))dlsym(RTLD_DEFAULT, "Py_IsInitialized");
  int py = alive && alive();
  fmi2FreeInstanceTYPE* f = real_lib ? (fmi2FreeInstanceTYPE*)dlsym(real_lib, "fmi2FreeInstance") : NULL;
  while (py && f && pool) { Slot* s = pool; pool = s->next; f(s->real); free(s); }
  pooled = 0;
  void (*fin)(void) = real_lib ? (void (*)(void))dlsym(real_lib, "finalizePythonInterpreter") : NULL;
  if (fin) fin();
  if (py && real_lib && uav_live_none() && !pool) { dlclose(real_lib); real_lib = NULL; }
}

static void* sym(const char* name) {
  if (!real_lib) {
    Dl_info info; char path[4096];
    if (!dladdr((void*)&sym, &info) || !info.dli_fname) { snprintf(load_error, sizeof load_error, "dladdr failed");
      return NULL; }
    strncpy(path, info.dli_fname, sizeof path - 1); path[sizeof path - 1] = 0;
    char* slash = strrchr(path, '/');
    if (slash) slash[1] = 0; else path[0] = 0;
    strncat(path, "@REAL@", sizeof path - strlen(path) - 1);
    real_lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!real_lib) { snprintf(load_error, sizeof load_error, "%s", dlerror()); return NULL; }
    atexit(on_unload);  /* registered after pythonfmu's static destructors: runs before them */
  }
  return dlsym(real_lib, name);
}
#define REAL(fn) static fn##TYPE* f = NULL; if (!f) f = (fn##TYPE*)sym(#fn); if (!f) return fmi2Error

/* a message to the importer as the logger's format with every '%' doubled (as the native layer does), so a
   logger that does not expand variadic arguments (ctypes, many bindings) still shows the text */
static void emit(const Inst* in, fmi2Status s, const char* category, const char* text) {
  char buf[2100]; size_t j = 0;
  for (size_t i = 0; text[i] && j + 2 < sizeof buf; ++i) { if (text[i] == '%') buf[j++] = '%'; buf[j++] = text[i]; }
  buf[j] = 0;
  in->cb.logger(in->cb.componentEnvironment, in->name, s, category, buf);
}

static void say(const Inst* in, fmi2Status s, const char* fmt, ...) {
  char buf[1024]; va_list ap;
  if (!in || !in->cb.logger) return;
  va_start(ap, fmt); vsnprintf(buf, sizeof buf, fmt, ap); va_end(ap);
  emit(in, s, s == fmi2Error ? "logStatusError" : s == fmi2Discard ? "logStatusDiscard" : "logAll", buf);
}

static Inst* find(fmi2Component c) {
  if (uav_live_find(c) < 0) return NULL;  /* compared by address: a foreign handle is never read */
  Inst* in = (Inst*)c;
  return in->magic == INST_MAGIC ? in : NULL;
}

/* The live instance c if fn is allowed in its state, else NULL after logging why. */
static Inst* enter(fmi2Component c, const char* fn, int allowed) {
  Inst* in = find(c);
  if (!in) return NULL;  /* NULL, freed or foreign handle: no logger to tell */
  if (!(in->state & allowed)) {
    say(in, fmi2Error, "%s: not allowed in state '%s' (FMI Co-Simulation state machine)", fn,
        uavfmu_state_name(in->state));
    return NULL;
  }
  in->logged_error = 0;  /* an error the slave logs during this call makes the call an fmi2Error */
  return in;
}

static fmi2Status after(Inst* in, const char* fn, fmi2Status s) {
  if (s == fmi2Fatal) {
    in->state = S_FATAL;
    say(in, fmi2Error, "%s: the model failed fatally; the instance is quarantined (only fmi2FreeInstance)", fn);
  } else if (s == fmi2Error || (s <= fmi2Warning && in->logged_error)) {
    s = fmi2Error;  /* our slave reports model failures by logging an error (it never raises into pythonfmu) */
    in->state = S_ERROR;
  }
  return s;
}

static const VarInfo* lookup(fmi2ValueReference vr) {
  size_t lo = 0, hi = NVARS;
  while (lo < hi) { size_t mid = (lo + hi) / 2; if (VARS[mid].vr < vr) lo = mid + 1; else hi = mid; }
  return (lo < NVARS && VARS[lo].vr == vr) ? &VARS[lo] : NULL;
}

static int check_refs(Inst* in, const char* fn, const fmi2ValueReference vr[], size_t nvr, const void* values,
                      char type, int setting) {
  if (nvr == 0) return 1;
  if (nvr > MAX_NVR) { say(in, fmi2Error, "%s: nvr = %zu exceeds %u", fn, nvr, MAX_NVR); return 0; }
  if (!vr || !values) { say(in, fmi2Error, "%s: NULL %s array for nvr = %zu", fn, vr ? "value" : "vr", nvr);
    return 0; }
  for (size_t i = 0; i < nvr; ++i) {
    const VarInfo* v = lookup(vr[i]);
    if (!v) { say(in, fmi2Error, "%s: value reference %u (index %zu) is not a variable of this FMU", fn, vr[i], i);
      return 0; }
    if (v->type != type) { say(in, fmi2Error, "%s: value reference %u is of type %c, not %c", fn, vr[i], v->type, type);
      return 0; }
    int mask = v->settable == 3 ? MASK_SetInput : v->settable == 2 ? MASK_SetTunable : v->settable == 1
               ? MASK_SetFixed : 0;
    if (setting && !(in->state & mask)) {
      say(in, fmi2Error, "%s: %s (%s) cannot be set in state '%s'", fn, v->name, v->settable == 3
          ? "input" : v->settable == 2 ? "tunable parameter" : v->settable ? "fixed parameter" : "output",
          uavfmu_state_name(in->state));
      return 0;
    }
    if (setting && type == 'S' && !((const fmi2String*)values)[i]) {
      say(in, fmi2Error, "%s: NULL string for value reference %u", fn, vr[i]); return 0; }
  }
  return 1;
}
"""

C_LIFECYCLE = r"""
const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }

static void forward_log(fmi2ComponentEnvironment env, fmi2String name, fmi2Status s, fmi2String cat,
                        fmi2String msg, ...) {
  /* pythonfmu passes its message as the format string: forwarded as a plain string, never formatted */
  const Slot* slot = (const Slot*)env;
  Inst* in = slot ? slot->owner : NULL;
  (void)name;
  if (in && s >= fmi2Error) in->logged_error = 1;
  if (in && in->cb.logger) emit(in, s, cat ? cat : "logAll", msg ? msg : "");
}

/* A pooled pythonfmu instance of the same FMU, reset, or a new one; NULL after logging why not. */
static Slot* take_slot(Inst* in, fmi2InstantiateTYPE* f, fmi2String n, fmi2String g, fmi2String r, fmi2Boolean v) {
  char key[4096];
  snprintf(key, sizeof key, "%s|%s", g, r);
  for (Slot** p = &pool; *p; p = &(*p)->next) {
    Slot* s = *p;
    if (strcmp(s->key, key)) continue;
    *p = s->next; --pooled;
    s->owner = in;
    fmi2ResetTYPE* reset = (fmi2ResetTYPE*)sym("fmi2Reset");
    if (reset && reset(s->real) <= fmi2Warning) return s;
    fmi2FreeInstanceTYPE* fr = (fmi2FreeInstanceTYPE*)sym("fmi2FreeInstance");
    if (fr) fr(s->real);
    free(s);
    break;
  }
  Slot* s = (Slot*)calloc(1, sizeof(Slot));
  if (!s) return NULL;
  snprintf(s->key, sizeof s->key, "%s", key);
  s->owner = in;
  s->cb.logger = forward_log; s->cb.allocateMemory = calloc; s->cb.freeMemory = free;
  s->cb.componentEnvironment = s;
  s->real = f(n, fmi2CoSimulation, g, r, &s->cb, v, fmi2True);
  if (!s->real) { free(s); return NULL; }
  return s;
}

fmi2Component fmi2Instantiate(fmi2String n, fmi2Type t, fmi2String g, fmi2String r,
                              const fmi2CallbackFunctions* cb, fmi2Boolean v, fmi2Boolean l) {
  (void)l;  /* always on: our slave logs only warnings and errors, which an importer must see */
  if (!cb || !cb->logger) return NULL;
  fmi2String who = (n && n[0]) ? n : "?";
  if (!n || !n[0]) { cb->logger(cb->componentEnvironment, who, fmi2Error, "logStatusError",
                                "fmi2Instantiate: instanceName must be a non-empty string"); return NULL; }
  if (MODEL_GUID[0] && (!g || strcmp(g, MODEL_GUID) != 0)) {
    cb->logger(cb->componentEnvironment, who, fmi2Error, "logStatusError",
               "fmi2Instantiate: GUID %s does not match this FMU's %s", g ? g : "(null)", MODEL_GUID);
    return NULL; }
  char derived[4200];
  if (!r) {  /* no resource location given (allowed): pythonfmu needs it, so it is found from this library */
    Dl_info info;
    if (!dladdr((void*)&fmi2Instantiate, &info) || !info.dli_fname || !realpath(info.dli_fname, derived + 7)) {
      cb->logger(cb->componentEnvironment, who, fmi2Error, "logStatusError",
                 "fmi2Instantiate: no fmuResourceLocation and this library's folder is unknown"); return NULL; }
    memcpy(derived, "file://", 7);
    for (int up = 0; up < 3; ++up) { char* sl = strrchr(derived + 7, '/'); if (sl) *sl = 0; }
    strncat(derived, "/resources", sizeof derived - strlen(derived) - 1);
    r = derived;
  }
  fmi2InstantiateTYPE* f = (fmi2InstantiateTYPE*)sym("fmi2Instantiate");
  if (!f) { cb->logger(cb->componentEnvironment, n, fmi2Error, "logStatusError", "cannot load @REAL@: %s",
                       load_error); return NULL; }
  if (t != fmi2CoSimulation) { cb->logger(cb->componentEnvironment, n, fmi2Error, "logStatusError",
                               "this FMU supports co-simulation only (fmuType %d)", (int)t); return NULL; }
  Inst* in = (Inst*)calloc(1, sizeof(Inst));
  if (!in) return NULL;
  in->cb = *cb;
  snprintf(in->name, sizeof in->name, "%s", n);
  in->live_slot = uav_live_add(in);
  if (in->live_slot < 0) {
    cb->logger(cb->componentEnvironment, n, fmi2Error, "logStatusError",
               "%d instances of this FMU are live already, the most one binary holds", UAV_MAX_INSTANCES);
    free(in); return NULL;
  }
  in->slot = take_slot(in, f, n, g, r, v);
  if (!in->slot) { uav_live_remove(in->live_slot, in); free(in); return NULL; }
  in->real = in->slot->real;
  in->magic = INST_MAGIC; in->state = S_INSTANTIATED; in->time = 0.0; in->dt = DT_START;
  return in;
}

static void drop_states(Inst* in) {
  fmi2FreeFMUstateTYPE* ff = (fmi2FreeFMUstateTYPE*)sym("fmi2FreeFMUstate");
  while (in->states) {
    State* s = in->states; in->states = s->next;
    if (ff && in->state != S_FATAL) ff(in->real, &s->real);
    s->magic = 0; free(s);
  }
}

void fmi2FreeInstance(fmi2Component c) {
  Inst* in = find(c);
  if (!in) return;  /* NULL, already freed or foreign: ignoring it is the only safe answer */
  drop_states(in);
  fmi2FreeInstanceTYPE* f = (fmi2FreeInstanceTYPE*)sym("fmi2FreeInstance");
  Slot* s = in->slot;
  s->owner = NULL;
  if (in->state == S_FATAL) {
    /* pythonfmu already released a fatal instance's Python objects: freeing it would release them again, so
       it and its callbacks (which pythonfmu still points at) are left allocated */
  } else if (pooled < POOL_MAX) {
    s->next = pool; pool = s; ++pooled;
  } else {
    if (f) f(in->real);
    free(s);
  }
  uav_live_remove(in->live_slot, in);
  in->magic = 0;
  free(in);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
  Inst* in = enter(c, "fmi2SetDebugLogging", MASK_SetDebugLogging);
  if (!in) return fmi2Error;
  char why[256];
  if (!uavfmu_rule_categories(why, sizeof why, n, cats)) {
    say(in, fmi2Error, "fmi2SetDebugLogging: %s", why); return fmi2Error; }
  REAL(fmi2SetDebugLogging);
  /* warnings and errors always reach the importer: pythonfmu keeps logging on for every category (a category
     list would filter out its error messages, and a pooled instance would keep the filter for its next owner);
     our slave logs nothing below warnings, so the importer's choice changes nothing it could see */
  (void)on;
  return after(in, "fmi2SetDebugLogging", f(in->real, fmi2True, 0, NULL));
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real t0, fmi2Boolean sd,
                               fmi2Real t1) {
  Inst* in = enter(c, "fmi2SetupExperiment", MASK_SetupExperiment);
  if (!in) return fmi2Error;
  char why[256];
  if (!uavfmu_rule_setup(why, sizeof why, td, tol, t0, sd, t1)) {
    say(in, fmi2Error, "fmi2SetupExperiment: %s", why);
    return fmi2Error;
  }
  REAL(fmi2SetupExperiment);
  fmi2Status s = after(in, "fmi2SetupExperiment", f(in->real, td, tol, t0, sd, t1));
  if (s <= fmi2Warning) in->time = t0;
  return s;
}

static fmi2Status transition(fmi2Component c, const char* fn, int allowed, int next) {
  Inst* in = enter(c, fn, allowed);
  if (!in) return fmi2Error;
  fmi2Status (*f)(fmi2Component) = (fmi2Status (*)(fmi2Component))sym(fn);
  if (!f) return fmi2Error;
  fmi2Status s = after(in, fn, f(in->real));
  if (s <= fmi2Warning) in->state = next;
  return s;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
  return transition(c, "fmi2EnterInitializationMode", MASK_EnterInitializationMode, S_INIT);
}
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
  return transition(c, "fmi2ExitInitializationMode", MASK_ExitInitializationMode, S_STEPPING);
}
fmi2Status fmi2Terminate(fmi2Component c) { return transition(c, "fmi2Terminate", MASK_Terminate, S_TERMINATED); }

fmi2Status fmi2Reset(fmi2Component c) {
  fmi2Status s = transition(c, "fmi2Reset", MASK_Reset, S_INSTANTIATED);
  Inst* in = find(c);
  if (in && s <= fmi2Warning) { in->time = 0.0; in->dt = DT_START; }
  return s;
}
"""

C_VALUES = r"""
#define GETSET(NAME, CTYPE, LETTER, SETTING, ALLOWED)                                              \
  fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, CTYPE value[]) {     \
    Inst* in = enter(c, #NAME, ALLOWED);                                                           \
    if (!in || !check_refs(in, #NAME, vr, nvr, value, LETTER, SETTING)) return fmi2Error;          \
    if (nvr == 0) return fmi2OK;                                                                   \
    REAL(NAME);                                                                                    \
    fmi2Status s = after(in, #NAME, f(in->real, vr, nvr, value));                                  \
    if (SETTING && LETTER == 'R' && s <= fmi2Warning)                                              \
      for (size_t i = 0; i < nvr; ++i) if ((long long)vr[i] == DT_VR) in->dt = *(const double*)&value[i]; \
    return s;                                                                                      \
  }
GETSET(fmi2GetReal, fmi2Real, 'R', 0, MASK_GetValue)
GETSET(fmi2GetInteger, fmi2Integer, 'I', 0, MASK_GetValue)
GETSET(fmi2GetBoolean, fmi2Boolean, 'B', 0, MASK_GetValue)
GETSET(fmi2GetString, fmi2String, 'S', 0, MASK_GetValue)
GETSET(fmi2SetReal, const fmi2Real, 'R', 1, MASK_SetInput)
GETSET(fmi2SetInteger, const fmi2Integer, 'I', 1, MASK_SetInput)
GETSET(fmi2SetBoolean, const fmi2Boolean, 'B', 1, MASK_SetInput)
GETSET(fmi2SetString, const fmi2String, 'S', 1, MASK_SetInput)

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean no_set_prior) {
  Inst* in = enter(c, "fmi2DoStep", MASK_DoStep);
  if (!in) return fmi2Error;
  char why[256];
  if (!uavfmu_rule_step(why, sizeof why, t, h, in->time) ||
      (DT_VR >= 0 && !uavfmu_rule_internal_steps(why, sizeof why, h, in->dt))) {
    say(in, fmi2Error, "fmi2DoStep: %s", why);
    return fmi2Error;
  }
  REAL(fmi2DoStep);
  fmi2Status s = f(in->real, t, h, no_set_prior);
  if (s == fmi2Discard) s = fmi2Error;  /* our slave returns False only after logging an error */
  s = after(in, "fmi2DoStep", s);
  if (s <= fmi2Warning) in->time = t + h;
  return s;
}

static fmi2Status unsupported(fmi2Component c, const char* fn, int mask) {
  Inst* in = enter(c, fn, mask);
  if (in) say(in, fmi2Error, "%s: not supported by this FMU", fn);
  return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t n,
    const fmi2ValueReference b[], size_t m, const fmi2Real d[], fmi2Real e[]) {
  (void)a; (void)n; (void)b; (void)m; (void)d; (void)e;
  return unsupported(c, "fmi2GetDirectionalDerivative", MASK_GetDirectionalDerivative); }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference a[], size_t n,
    const fmi2Integer b[], const fmi2Real d[]) {
  (void)a; (void)n; (void)b; (void)d; return unsupported(c, "fmi2SetRealInputDerivatives", MASK_SetInputDerivatives); }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference a[], size_t n,
    const fmi2Integer b[], fmi2Real d[]) {
  (void)a; (void)n; (void)b; (void)d;
  return unsupported(c, "fmi2GetRealOutputDerivatives", MASK_GetOutputDerivatives); }
/* fmi2DoStep is synchronous: StepInProgress is never entered, so this is always a state error */
fmi2Status fmi2CancelStep(fmi2Component c) { enter(c, "fmi2CancelStep", MASK_CancelStep); return fmi2Error; }

/* as the native layer (fmu_models/fmi/native/fmi2Functions.c): fmi2LastSuccessfulTime and fmi2Terminated are
   answered, the kinds about an asynchronous step are not available (fmi2Discard) */
static fmi2Status get_status(fmi2Component c, const char* fn, fmi2StatusKind k, int kind, void* v) {
  Inst* in = enter(c, fn, MASK_GetStatus);
  if (!in) return fmi2Error;
  if (!v) { say(in, fmi2Error, "%s: value is NULL", fn); return fmi2Error; }
  if (!uavfmu_status_available(kind, (int)k)) {
    say(in, fmi2Discard, "%s: status kind %d is not available (no asynchronous step)", fn, (int)k);
    return fmi2Discard;
  }
  if (k == fmi2LastSuccessfulTime) *(fmi2Real*)v = in->time; else *(fmi2Boolean*)v = fmi2False;
  return fmi2OK;
}
#define GET_STATUS(Type, TypeName, kind)                                                      \
  fmi2Status fmi2Get##Type##Status(fmi2Component c, const fmi2StatusKind k, TypeName* v) {   \
    return get_status(c, "fmi2Get" #Type "Status", k, kind, v);                              \
  }
GET_STATUS(, fmi2Status, fmi2DoStepStatus)
GET_STATUS(Real, fmi2Real, fmi2LastSuccessfulTime)
GET_STATUS(Integer, fmi2Integer, -1)
GET_STATUS(Boolean, fmi2Boolean, fmi2Terminated)
GET_STATUS(String, fmi2String, fmi2PendingStatus)
#undef GET_STATUS
"""

C_STATES = r"""
static State* owned(Inst* in, const char* fn, fmi2FMUstate s) {
  for (State* p = in->states; p; p = p->next) if ((void*)p == s && p->magic == STATE_MAGIC) return p;
  say(in, fmi2Error, "%s: this FMU state was not made by this instance (or was freed)", fn);
  return NULL;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* out) {
  Inst* in = enter(c, "fmi2GetFMUstate", MASK_FMUState);
  if (!in) return fmi2Error;
  if (!out) { say(in, fmi2Error, "fmi2GetFMUstate: NULL state pointer"); return fmi2Error; }
  State* st = *out ? owned(in, "fmi2GetFMUstate", *out) : NULL;
  if (*out && !st) return fmi2Error;
  REAL(fmi2GetFMUstate);
  fmi2FMUstate real = NULL;
  fmi2Status s = after(in, "fmi2GetFMUstate", f(in->real, &real));
  if (s > fmi2Warning) return s;
  if (st) {  /* overwrite an existing state: release the old snapshot */
    fmi2FreeFMUstateTYPE* ff = (fmi2FreeFMUstateTYPE*)sym("fmi2FreeFMUstate");
    if (ff) ff(in->real, &st->real);
  } else {
    st = (State*)calloc(1, sizeof(State));
    if (!st) { say(in, fmi2Error, "fmi2GetFMUstate: out of memory"); return fmi2Error; }
    st->magic = STATE_MAGIC; st->owner = in; st->next = in->states; in->states = st;
  }
  st->real = real; st->time = in->time; st->mstate = in->state; st->dt = in->dt;
  *out = st;
  return s;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
  Inst* in = enter(c, "fmi2SetFMUstate", MASK_FMUState);
  State* st = in ? owned(in, "fmi2SetFMUstate", s) : NULL;
  if (!st) return fmi2Error;
  REAL(fmi2SetFMUstate);
  fmi2Status r = after(in, "fmi2SetFMUstate", f(in->real, st->real));
  if (r <= fmi2Warning) { in->time = st->time; in->state = st->mstate; in->dt = st->dt; }
  return r;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* s) {
  Inst* in = enter(c, "fmi2FreeFMUstate", MASK_FMUState);
  if (!in) return fmi2Error;
  if (!s || !*s) return fmi2OK;  /* freeing NULL is a no-op */
  State* st = owned(in, "fmi2FreeFMUstate", *s);
  if (!st) return fmi2Error;
  REAL(fmi2FreeFMUstate);
  fmi2Status r = after(in, "fmi2FreeFMUstate", f(in->real, &st->real));
  for (State** p = &in->states; *p; p = &(*p)->next) if (*p == st) { *p = st->next; break; }
  st->magic = 0; free(st);
  *s = NULL;
  return r;
}

static uint64_t fnv(const fmi2Byte* b, size_t n) {
  uint64_t h = 1469598103934665603ULL;
  for (size_t i = 0; i < n; ++i) { h ^= (unsigned char)b[i]; h *= 1099511628211ULL; }
  return h;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t* n) {
  Inst* in = enter(c, "fmi2SerializedFMUstateSize", MASK_FMUState);
  State* st = in ? owned(in, "fmi2SerializedFMUstateSize", s) : NULL;
  if (!st) return fmi2Error;
  if (!n) { say(in, fmi2Error, "fmi2SerializedFMUstateSize: NULL size pointer"); return fmi2Error; }
  REAL(fmi2SerializedFMUstateSize);
  size_t m = 0;
  fmi2Status r = after(in, "fmi2SerializedFMUstateSize", f(in->real, st->real, &m));
  if (r <= fmi2Warning) *n = m + SER_HEADER;
  return r;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
  Inst* in = enter(c, "fmi2SerializeFMUstate", MASK_FMUState);
  State* st = in ? owned(in, "fmi2SerializeFMUstate", s) : NULL;
  if (!st) return fmi2Error;
  REAL(fmi2SerializedFMUstateSize);
  size_t m = 0;
  if (after(in, "fmi2SerializeFMUstate", f(in->real, st->real, &m)) > fmi2Warning) return fmi2Error;
  if (!b || n != m + SER_HEADER) {
    say(in, fmi2Error, "fmi2SerializeFMUstate: buffer %s of %zu bytes, the state needs %zu", b ? "" : "NULL", n,
        m + SER_HEADER);
    return fmi2Error;
  }
  fmi2SerializeFMUstateTYPE* g = (fmi2SerializeFMUstateTYPE*)sym("fmi2SerializeFMUstate");
  if (!g) return fmi2Error;
  fmi2Status r = after(in, "fmi2SerializeFMUstate", g(in->real, st->real, b + SER_HEADER, m));
  if (r > fmi2Warning) return r;
  uint64_t key = MODEL_KEY, ms = (uint64_t)st->mstate;
  memcpy(b, SER_MAGIC, 8); memcpy(b + 8, &key, 8); memcpy(b + 24, &st->time, 8); memcpy(b + 32, &ms, 8);
  memcpy(b + 40, &st->dt, 8);
  uint64_t sum = fnv(b + 24, m + SER_HEADER - 24);
  memcpy(b + 16, &sum, 8);
  return r;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate* out) {
  Inst* in = enter(c, "fmi2DeSerializeFMUstate", MASK_FMUState);
  if (!in) return fmi2Error;
  uint64_t key = 0, sum = 0, ms = 0; double t = 0.0, dt = 0.0;
  if (!b || !out || n < SER_HEADER) {
    say(in, fmi2Error, "fmi2DeSerializeFMUstate: %s", !b || !out ? "NULL argument" : "shorter than the header");
    return fmi2Error;
  }
  memcpy(&key, b + 8, 8); memcpy(&sum, b + 16, 8); memcpy(&t, b + 24, 8); memcpy(&ms, b + 32, 8);
  memcpy(&dt, b + 40, 8);
  if (memcmp(b, SER_MAGIC, 8) || key != MODEL_KEY || sum != fnv(b + 24, n - 24) || !isfinite(t)
      || !(ms == S_INSTANTIATED || ms == S_INIT || ms == S_STEPPING || ms == S_TERMINATED || ms == S_ERROR)) {
    say(in, fmi2Error, "fmi2DeSerializeFMUstate: not a serialised state of this model (or damaged)");
    return fmi2Error;
  }
  REAL(fmi2DeSerializeFMUstate);
  fmi2FMUstate real = NULL;
  fmi2Status r = after(in, "fmi2DeSerializeFMUstate", f(in->real, b + SER_HEADER, n - SER_HEADER, &real));
  if (r > fmi2Warning) return r;
  State* st = (State*)calloc(1, sizeof(State));
  if (!st) { say(in, fmi2Error, "fmi2DeSerializeFMUstate: out of memory"); return fmi2Error; }
  st->magic = STATE_MAGIC; st->owner = in; st->real = real; st->time = t; st->mstate = (int)ms; st->dt = dt;
  st->next = in->states; in->states = st;
  *out = st;
  return r;
}
"""


def _table_c(rows: list[VarRow], model_identifier: str, guid: str) -> str:
    body = ",\n".join(f"  {{{r[0]}u, '{r[1]}', {r[2]}, {json.dumps(r[3])}}}" for r in rows)
    dt = next(((r[0], r[4]) for r in rows if r[3] == INTERNAL_STEP and r[4] is not None), (-1, 0.0))
    body = body or '  {0u, 0, 0, ""}'
    key = 1469598103934665603
    for ch in f"{model_identifier}:{[r[:3] for r in rows]}".encode():
        key = ((key ^ ch) * 1099511628211) % (1 << 64)
    return (f"static const VarInfo VARS[] = {{\n{body}\n}};\n"
            f"static const size_t NVARS = {len(rows)};\n"
            f"#define DT_VR {dt[0]}LL\n#define DT_START {dt[1]!r}\n"
            f"#define MODEL_KEY 0x{key:016x}ULL\n"
            f"static const char MODEL_GUID[] = \"{guid.replace(chr(92), '').replace(chr(34), '')}\";\n")


def shim_source(real_library_name: str, rows: list[VarRow] | None = None, model_identifier: str = "",
                guid: str = "") -> str:
    """C source of the guarding library for the variables ``rows`` (``variable_table``) of the FMU ``guid``."""
    core = C_CORE.replace("@TABLE@", _table_c(rows or [], model_identifier or real_library_name, guid))
    return (core + C_LIFECYCLE + C_VALUES + C_STATES).replace("@REAL@", real_library_name)


def build_shim(model_identifier: str, out_dir: Path, compiler: str, rows: list[VarRow] | None = None,
               guid: str = "") -> Path:
    """Compile ``<id>.so`` guarding and forwarding to ``<id>_pythonfmu.so``; return its path."""
    (out_dir / "uavfmu_states.h").write_text(statemachine.header())
    (out_dir / "uavfmu_live.h").write_bytes((Path(__file__).parent / "native" / "uavfmu_live.h").read_bytes())
    src = out_dir / f"{model_identifier}_shim.c"
    src.write_text(shim_source(f"{model_identifier}_pythonfmu.so", rows, model_identifier, guid))
    lib = out_dir / f"{model_identifier}.so"
    compile_library(src, lib, compiler, extra=["-I", str(HEADERS), "-I", str(out_dir), "-ldl"])
    return lib
