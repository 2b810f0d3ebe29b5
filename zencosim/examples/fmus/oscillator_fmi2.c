/* The zencosim example oscillator as an FMI 2.0 FMU: Co-Simulation and Model Exchange in one binary.

   One point mass on a line, with a spring and damper to ground, a coupling spring-damper towards a
   "terminal" whose motion arrives as inputs (x_in, v_in), and an applied input force f_in:

     fc           = kc*(x - x_in) + cc*(v - v_in)      force of the coupling element on the terminal (the remote mass);
                                                        the mass feels its reaction -fc
     a            = (-k*x - c*v - fc + f_in) / m
     inverse_mass = 1/m
     E            = 0.5*m*v*v + 0.5*k*x*x + 0.5*kc*(x - x_in)*(x - x_in)

   Co-Simulation: each doStep(t, h) is one symplectic Euler step, kick then drift:
   v = v + h*a(x, v, inputs); x = x + h*v. Model Exchange: states [x, v], derivatives [v, a].
   x and v start at the parameters x0 and v0 when initialization mode is exited. A doStep starting
   at or after fail_at (and, in Model Exchange, fmi2GetDerivatives at such a time) fails.

   VR_*, N_VARIABLES, START_VALUES, CAUSALITIES (of INDEPENDENT, PARAMETER, INPUT, OUTPUT),
   INSTANTIATION_TOKEN and CAN_* come from oscillator_table.h,
   which build.py generates from its table of variables (the same table makes modelDescription.xml).
   Functions of the FMI 2.0 API that do not apply to this model return fmi2Error and log why. */

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "oscillator_table.h"

#define N_STATES 2
#define STATE_SIZE (3 * sizeof(double)) /* a serialized FMU state: time, x, v */

typedef enum { INSTANTIATED, INITIALIZATION, STEP, EVENT, CONTINUOUS_TIME, TERMINATED } Mode;

typedef struct {
    double value[N_VARIABLES]; /* every variable by value reference; x and v are the states */
    fmi2Type type;
    Mode mode;
    char *name;
    const fmi2CallbackFunctions *functions;
    fmi2Boolean logging_on;
} Instance;

typedef struct {
    double time, x, v;
} State;

/* Send a message to the environment's logger; OK-status messages only when debug logging is on. */
static void log_message(Instance *inst, fmi2Status status, const char *format, ...)
    __attribute__((format(printf, 3, 4)));

static void log_message(Instance *inst, fmi2Status status, const char *format, ...) {
    char message[512], escaped[1024];
    size_t i, j;
    va_list args;
    if (!inst || !inst->functions || !inst->functions->logger) return;
    if (status == fmi2OK && !inst->logging_on) return;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    for (i = 0, j = 0; message[i] && j < sizeof escaped - 2; i++) { /* the logger takes a format: % becomes %% */
        if (message[i] == '%') escaped[j++] = '%';
        escaped[j++] = message[i];
    }
    escaped[j] = '\0';
    inst->functions->logger(inst->functions->componentEnvironment, inst->name, status,
                            status == fmi2OK ? "logAll" : "logStatusError", escaped);
}

/* The answer of every function that does not apply to this model. */
static fmi2Status unsupported(fmi2Component c, const char *function) {
    log_message((Instance *)c, fmi2Error, "%s is not supported by this FMU", function);
    return fmi2Error;
}

/* Before initialization mode is exited the states follow their start parameters x0 and v0. */
static void update_states(Instance *inst) {
    double *p = inst->value;
    if (inst->mode == INSTANTIATED || inst->mode == INITIALIZATION) {
        p[VR_x] = p[VR_x0];
        p[VR_v] = p[VR_v0];
    }
}

/* The outputs a, fc, inverse_mass and E from the current states, parameters and inputs. */
static void update_outputs(Instance *inst) {
    double *p = inst->value, x, v, x_in = p[VR_x_in];
    update_states(inst);
    x = p[VR_x];
    v = p[VR_v];
    p[VR_fc] = p[VR_kc] * (x - x_in) + p[VR_cc] * (v - p[VR_v_in]);
    p[VR_a] = (-p[VR_k] * x - p[VR_c] * v - p[VR_fc] + p[VR_f_in]) / p[VR_m];
    p[VR_inverse_mass] = 1.0 / p[VR_m];
    p[VR_E] = 0.5 * p[VR_m] * v * v + 0.5 * p[VR_k] * x * x + 0.5 * p[VR_kc] * (x - x_in) * (x - x_in);
}

static void set_start_values(Instance *inst) {
    const double start[N_VARIABLES] = START_VALUES;
    memcpy(inst->value, start, sizeof start);
    update_outputs(inst);
}

/* Checks that c is an instance in one of the modes allowed (a bit mask of 1 << mode). */
static int allowed(fmi2Component c, const char *function, int modes) {
    Instance *inst = (Instance *)c;
    if (!inst) return 0;
    if (!(modes & (1 << inst->mode))) {
        log_message(inst, fmi2Error, "%s is not allowed in mode %d", function, (int)inst->mode);
        return 0;
    }
    return 1;
}

#define ANY_MODE 0xff
#define BEFORE_INIT_END ((1 << INSTANTIATED) | (1 << INITIALIZATION))
#define ME_MODES ((1 << INITIALIZATION) | (1 << EVENT) | (1 << CONTINUOUS_TIME) | (1 << TERMINATED))

/* ---- Common functions ---- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    if (!allowed(c, "fmi2SetDebugLogging", ANY_MODE)) return fmi2Error;
    ((Instance *)c)->logging_on = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    Instance *inst = calloc(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->functions = functions;
    inst->logging_on = loggingOn;
    inst->type = fmuType;
    inst->name = malloc(strlen(instanceName ? instanceName : "") + 1);
    if (!inst->name) {
        free(inst);
        return NULL;
    }
    strcpy(inst->name, instanceName ? instanceName : "");
    if (!fmuGUID || strcmp(fmuGUID, INSTANTIATION_TOKEN) != 0) {
        log_message(inst, fmi2Error, "fmi2Instantiate: GUID %s does not match %s", fmuGUID ? fmuGUID : "(null)",
                    INSTANTIATION_TOKEN);
        fmi2FreeInstance(inst);
        return NULL;
    }
    inst->mode = INSTANTIATED;
    set_start_values(inst);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!inst) return;
    free(inst->name);
    free(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    if (!allowed(c, "fmi2SetupExperiment", 1 << INSTANTIATED)) return fmi2Error;
    ((Instance *)c)->value[VR_time] = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    if (!allowed(c, "fmi2EnterInitializationMode", 1 << INSTANTIATED)) return fmi2Error;
    ((Instance *)c)->mode = INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(c, "fmi2ExitInitializationMode", 1 << INITIALIZATION)) return fmi2Error;
    if (!(inst->value[VR_m] > 0.0)) {
        log_message(inst, fmi2Error, "fmi2ExitInitializationMode: the mass m = %g must be positive", inst->value[VR_m]);
        return fmi2Error;
    }
    update_outputs(inst); /* x = x0, v = v0 */
    inst->mode = inst->type == fmi2CoSimulation ? STEP : EVENT;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    if (!allowed(c, "fmi2Terminate", (1 << STEP) | (1 << EVENT) | (1 << CONTINUOUS_TIME))) return fmi2Error;
    ((Instance *)c)->mode = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    if (!allowed(c, "fmi2Reset", ANY_MODE)) return fmi2Error;
    ((Instance *)c)->mode = INSTANTIATED;
    set_start_values((Instance *)c);
    return fmi2OK;
}

/* ---- Getting and setting variable values ---- */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    size_t i;
    if (!allowed(c, "fmi2GetReal", ANY_MODE)) return fmi2Error;
    update_outputs(inst);
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= N_VARIABLES) {
            log_message(inst, fmi2Error, "fmi2GetReal: no variable has value reference %u", vr[i]);
            return fmi2Error;
        }
        value[i] = inst->value[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    const int causality[N_VARIABLES] = CAUSALITIES;
    size_t i;
    if (!allowed(c, "fmi2SetReal", ANY_MODE & ~(1 << TERMINATED))) return fmi2Error;
    for (i = 0; i < nvr; i++) { /* check everything before changing anything */
        int kind = vr[i] < N_VARIABLES ? causality[vr[i]] : OUTPUT;
        if (kind != INPUT && !(kind == PARAMETER && (BEFORE_INIT_END & (1 << inst->mode)))) {
            log_message(inst, fmi2Error, "fmi2SetReal: value reference %u cannot be set in mode %d", vr[i],
                        (int)inst->mode);
            return fmi2Error;
        }
    }
    for (i = 0; i < nvr; i++) inst->value[vr[i]] = value[i];
    return fmi2OK;
}

/* This model has no Integer, Boolean or String variables: only empty requests succeed. */
static fmi2Status no_variables(fmi2Component c, const char *function, size_t nvr) {
    if (!allowed(c, function, ANY_MODE)) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    log_message((Instance *)c, fmi2Error, "%s: this FMU has no variables of that type", function);
    return fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    return no_variables(c, "fmi2GetInteger", nvr);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    return no_variables(c, "fmi2GetBoolean", nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    return no_variables(c, "fmi2GetString", nvr);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    return no_variables(c, "fmi2SetInteger", nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    return no_variables(c, "fmi2SetBoolean", nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    return no_variables(c, "fmi2SetString", nvr);
}

/* ---- FMU state: a copy of (time, x, v) ---- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    State *state;
    if (!CAN_GET_AND_SET_STATE) return unsupported(c, "fmi2GetFMUstate");
    if (!allowed(c, "fmi2GetFMUstate", ANY_MODE)) return fmi2Error;
    update_states(inst);
    state = *FMUstate ? (State *)*FMUstate : malloc(sizeof(State)); /* an existing state is overwritten */
    if (!state) return fmi2Error;
    state->time = inst->value[VR_time];
    state->x = inst->value[VR_x];
    state->v = inst->value[VR_v];
    *FMUstate = state;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Instance *inst = (Instance *)c;
    const State *state = (const State *)FMUstate;
    if (!CAN_GET_AND_SET_STATE) return unsupported(c, "fmi2SetFMUstate");
    if (!allowed(c, "fmi2SetFMUstate", ANY_MODE)) return fmi2Error;
    if (!state) {
        log_message(inst, fmi2Error, "fmi2SetFMUstate: the state is NULL");
        return fmi2Error;
    }
    inst->value[VR_time] = state->time;
    inst->value[VR_x] = state->x;
    inst->value[VR_v] = state->v;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    if (!CAN_GET_AND_SET_STATE) return unsupported(c, "fmi2FreeFMUstate");
    if (!allowed(c, "fmi2FreeFMUstate", ANY_MODE)) return fmi2Error;
    free(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    if (!CAN_SERIALIZE_STATE) return unsupported(c, "fmi2SerializedFMUstateSize");
    if (!allowed(c, "fmi2SerializedFMUstateSize", ANY_MODE)) return fmi2Error;
    *size = STATE_SIZE;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    const State *state = (const State *)FMUstate;
    double values[3];
    if (!CAN_SERIALIZE_STATE) return unsupported(c, "fmi2SerializeFMUstate");
    if (!allowed(c, "fmi2SerializeFMUstate", ANY_MODE)) return fmi2Error;
    if (!state || size < STATE_SIZE) {
        log_message((Instance *)c, fmi2Error, "fmi2SerializeFMUstate: no state, or a buffer of %zu < %zu bytes",
                    size, STATE_SIZE);
        return fmi2Error;
    }
    values[0] = state->time;
    values[1] = state->x;
    values[2] = state->v;
    memcpy(serializedState, values, STATE_SIZE);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    double values[3];
    State *state;
    if (!CAN_SERIALIZE_STATE) return unsupported(c, "fmi2DeSerializeFMUstate");
    if (!allowed(c, "fmi2DeSerializeFMUstate", ANY_MODE)) return fmi2Error;
    if (size != STATE_SIZE) {
        log_message((Instance *)c, fmi2Error, "fmi2DeSerializeFMUstate: %zu bytes, expected %zu", size, STATE_SIZE);
        return fmi2Error;
    }
    state = *FMUstate ? (State *)*FMUstate : malloc(sizeof(State));
    if (!state) return fmi2Error;
    memcpy(values, serializedState, STATE_SIZE);
    state->time = values[0];
    state->x = values[1];
    state->v = values[2];
    *FMUstate = state;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

/* ---- Model Exchange ---- */

/* Checks that c is a Model Exchange instance in one of the modes allowed. */
static int model_exchange(fmi2Component c, const char *function, int modes) {
    if (c && ((Instance *)c)->type != fmi2ModelExchange) {
        log_message((Instance *)c, fmi2Error, "%s: not a Model Exchange instance", function);
        return 0;
    }
    return allowed(c, function, modes);
}

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    if (!model_exchange(c, "fmi2EnterEventMode", (1 << EVENT) | (1 << CONTINUOUS_TIME))) return fmi2Error;
    ((Instance *)c)->mode = EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    if (!model_exchange(c, "fmi2NewDiscreteStates", 1 << EVENT)) return fmi2Error;
    eventInfo->newDiscreteStatesNeeded = fmi2False; /* no events: nothing ever changes discontinuously */
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False;
    eventInfo->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    if (!model_exchange(c, "fmi2EnterContinuousTimeMode", 1 << EVENT)) return fmi2Error;
    ((Instance *)c)->mode = CONTINUOUS_TIME;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    if (!model_exchange(c, "fmi2CompletedIntegratorStep", 1 << CONTINUOUS_TIME)) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    if (!model_exchange(c, "fmi2SetTime", (1 << EVENT) | (1 << CONTINUOUS_TIME))) return fmi2Error;
    ((Instance *)c)->value[VR_time] = time;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (!model_exchange(c, "fmi2SetContinuousStates", (1 << EVENT) | (1 << CONTINUOUS_TIME))) return fmi2Error;
    if (nx != N_STATES) {
        log_message(inst, fmi2Error, "fmi2SetContinuousStates: nx = %zu, the FMU has %d states", nx, N_STATES);
        return fmi2Error;
    }
    inst->value[VR_x] = x[0];
    inst->value[VR_v] = x[1];
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (!model_exchange(c, "fmi2GetDerivatives", ME_MODES)) return fmi2Error;
    if (nx != N_STATES) {
        log_message(inst, fmi2Error, "fmi2GetDerivatives: nx = %zu, the FMU has %d states", nx, N_STATES);
        return fmi2Error;
    }
    if (inst->value[VR_time] >= inst->value[VR_fail_at]) {
        log_message(inst, fmi2Error, "fmi2GetDerivatives: time %.17g is at or after fail_at = %.17g",
                    inst->value[VR_time], inst->value[VR_fail_at]);
        return fmi2Error;
    }
    update_outputs(inst);
    derivatives[0] = inst->value[VR_v];
    derivatives[1] = inst->value[VR_a];
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    if (!model_exchange(c, "fmi2GetEventIndicators", ME_MODES)) return fmi2Error;
    if (ni == 0) return fmi2OK;
    log_message((Instance *)c, fmi2Error, "fmi2GetEventIndicators: ni = %zu, the FMU has no event indicators", ni);
    return fmi2Error;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (!model_exchange(c, "fmi2GetContinuousStates", ME_MODES)) return fmi2Error;
    if (nx != N_STATES) {
        log_message(inst, fmi2Error, "fmi2GetContinuousStates: nx = %zu, the FMU has %d states", nx, N_STATES);
        return fmi2Error;
    }
    update_states(inst);
    x[0] = inst->value[VR_x];
    x[1] = inst->value[VR_v];
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    if (!model_exchange(c, "fmi2GetNominalsOfContinuousStates", ANY_MODE)) return fmi2Error;
    if (nx != N_STATES) {
        log_message((Instance *)c, fmi2Error, "fmi2GetNominalsOfContinuousStates: nx = %zu, the FMU has %d states",
                    nx, N_STATES);
        return fmi2Error;
    }
    x_nominal[0] = 1.0;
    x_nominal[1] = 1.0;
    return fmi2OK;
}

/* ---- Co-Simulation ---- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    return unsupported(c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

/* One symplectic Euler step (kick, then drift) from currentCommunicationPoint over communicationStepSize. */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *inst = (Instance *)c;
    double *p, h = communicationStepSize;
    if (inst && inst->type != fmi2CoSimulation) {
        log_message(inst, fmi2Error, "fmi2DoStep: not a Co-Simulation instance");
        return fmi2Error;
    }
    if (!allowed(c, "fmi2DoStep", 1 << STEP)) return fmi2Error;
    p = inst->value;
    if (!(h > 0.0)) {
        log_message(inst, fmi2Error, "fmi2DoStep: the step size %g is not positive", h);
        return fmi2Error;
    }
    if (currentCommunicationPoint >= p[VR_fail_at]) {
        log_message(inst, fmi2Error, "fmi2DoStep: the step starts at %.17g, at or after fail_at = %.17g",
                    currentCommunicationPoint, p[VR_fail_at]);
        return fmi2Error;
    }
    update_outputs(inst); /* a from the state and inputs at the start of the step */
    p[VR_v] = p[VR_v] + h * p[VR_a];
    p[VR_x] = p[VR_x] + h * p[VR_v];
    p[VR_time] = currentCommunicationPoint + h;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    return unsupported(c, "fmi2GetStatus"); /* doStep never returns fmi2Pending */
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (s != fmi2LastSuccessfulTime) return unsupported(c, "fmi2GetRealStatus (other than fmi2LastSuccessfulTime)");
    if (!allowed(c, "fmi2GetRealStatus", ANY_MODE)) return fmi2Error;
    *value = ((Instance *)c)->value[VR_time];
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    return unsupported(c, "fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (s != fmi2Terminated) return unsupported(c, "fmi2GetBooleanStatus (other than fmi2Terminated)");
    if (!allowed(c, "fmi2GetBooleanStatus", ANY_MODE)) return fmi2Error;
    *value = fmi2False; /* the FMU never asks to end the simulation */
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    return unsupported(c, "fmi2GetStringStatus");
}
