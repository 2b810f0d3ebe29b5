/* The zencosim example oscillator as an FMI 3.0 Co-Simulation FMU.

   The model and its arithmetic are those of oscillator_fmi2.c (described there), statement for
   statement, so that both FMUs give the same trajectories bit for bit:

     fc           = kc*(x - x_in) + cc*(v - v_in)
     a            = (-k*x - c*v - fc + f_in) / m
     inverse_mass = 1/m
     E            = 0.5*m*v*v + 0.5*k*x*x + 0.5*kc*(x - x_in)*(x - x_in)

   Each fmi3DoStep(t, h) is one symplectic Euler step, kick then drift: v = v + h*a; x = x + h*v.
   x and v start at x0 and v0 when initialization mode is exited; a step starting at or after
   fail_at fails. No event mode, no early return, no intermediate update.

   VR_*, N_VARIABLES, START_VALUES, CAUSALITIES (of INDEPENDENT, PARAMETER, INPUT, OUTPUT),
   INSTANTIATION_TOKEN and CAN_* come from oscillator_table.h, which build.py generates from its
   table of variables (the same table makes modelDescription.xml). Functions of the FMI 3.0 API
   that do not apply to this FMU return fmi3Error and log why. */

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "oscillator_table.h"

#define STATE_SIZE (3 * sizeof(double)) /* a serialized FMU state: time, x, v */

typedef enum { INSTANTIATED, INITIALIZATION, STEP, TERMINATED } Mode;

typedef struct {
    double value[N_VARIABLES]; /* every variable by value reference; x and v are the states */
    Mode mode;
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log;
    fmi3Boolean logging_on;
} Instance;

typedef struct {
    double time, x, v;
} State;

/* Send a message to the environment's logger; OK-status messages only when debug logging is on. */
static void log_message(Instance *inst, fmi3Status status, const char *format, ...)
    __attribute__((format(printf, 3, 4)));

static void log_message(Instance *inst, fmi3Status status, const char *format, ...) {
    char message[512];
    va_list args;
    if (!inst || !inst->log) return;
    if (status == fmi3OK && !inst->logging_on) return;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    inst->log(inst->environment, status, status == fmi3OK ? "logAll" : "logStatusError", message);
}

/* The answer of every function that does not apply to this FMU. */
static fmi3Status unsupported(fmi3Instance instance, const char *function) {
    log_message((Instance *)instance, fmi3Error, "%s is not supported by this FMU", function);
    return fmi3Error;
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

/* Checks that instance is an instance in one of the modes allowed (a bit mask of 1 << mode). */
static int allowed(fmi3Instance instance, const char *function, int modes) {
    Instance *inst = (Instance *)instance;
    if (!inst) return 0;
    if (!(modes & (1 << inst->mode))) {
        log_message(inst, fmi3Error, "%s is not allowed in mode %d", function, (int)inst->mode);
        return 0;
    }
    return 1;
}

#define ANY_MODE 0xff
#define BEFORE_INIT_END ((1 << INSTANTIATED) | (1 << INITIALIZATION))

/* ---- Inquire version numbers and set debug logging ---- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    if (!allowed(instance, "fmi3SetDebugLogging", ANY_MODE)) return fmi3Error;
    ((Instance *)instance)->logging_on = loggingOn;
    return fmi3OK;
}

/* ---- Creation and destruction of FMU instances ---- */

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU offers Co-Simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    Instance *inst = calloc(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->environment = instanceEnvironment;
    inst->log = logMessage;
    inst->logging_on = loggingOn;
    if (!instantiationToken || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        log_message(inst, fmi3Error, "fmi3InstantiateCoSimulation: instantiation token %s does not match %s",
                    instantiationToken ? instantiationToken : "(null)", INSTANTIATION_TOKEN);
        free(inst);
        return NULL;
    }
    if (eventModeUsed) {
        log_message(inst, fmi3Error, "fmi3InstantiateCoSimulation: this FMU has no event mode");
        free(inst);
        return NULL;
    }
    inst->mode = INSTANTIATED;
    set_start_values(inst);
    return inst;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "this FMU offers Co-Simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

/* ---- Enter and exit initialization mode, enter event mode, terminate and reset ---- */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    if (!allowed(instance, "fmi3EnterInitializationMode", 1 << INSTANTIATED)) return fmi3Error;
    ((Instance *)instance)->value[VR_time] = startTime;
    ((Instance *)instance)->mode = INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (!allowed(instance, "fmi3ExitInitializationMode", 1 << INITIALIZATION)) return fmi3Error;
    if (!(inst->value[VR_m] > 0.0)) {
        log_message(inst, fmi3Error, "fmi3ExitInitializationMode: the mass m = %g must be positive", inst->value[VR_m]);
        return fmi3Error;
    }
    update_outputs(inst); /* x = x0, v = v0 */
    inst->mode = STEP;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) { return unsupported(instance, "fmi3EnterEventMode"); }

fmi3Status fmi3Terminate(fmi3Instance instance) {
    if (!allowed(instance, "fmi3Terminate", 1 << STEP)) return fmi3Error;
    ((Instance *)instance)->mode = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (!allowed(instance, "fmi3Reset", ANY_MODE)) return fmi3Error;
    ((Instance *)instance)->mode = INSTANTIATED;
    set_start_values((Instance *)instance);
    return fmi3OK;
}

/* ---- Getting and setting variable values ---- */

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    size_t i;
    if (!allowed(instance, "fmi3GetFloat64", ANY_MODE)) return fmi3Error;
    if (nValues != nValueReferences) {
        log_message(inst, fmi3Error, "fmi3GetFloat64: %zu values for %zu scalar variables", nValues, nValueReferences);
        return fmi3Error;
    }
    update_outputs(inst);
    for (i = 0; i < nValueReferences; i++) {
        if (valueReferences[i] >= N_VARIABLES) {
            log_message(inst, fmi3Error, "fmi3GetFloat64: no variable has value reference %u", valueReferences[i]);
            return fmi3Error;
        }
        values[i] = inst->value[valueReferences[i]];
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues) {
    Instance *inst = (Instance *)instance;
    const int causality[N_VARIABLES] = CAUSALITIES;
    size_t i;
    if (!allowed(instance, "fmi3SetFloat64", ANY_MODE & ~(1 << TERMINATED))) return fmi3Error;
    if (nValues != nValueReferences) {
        log_message(inst, fmi3Error, "fmi3SetFloat64: %zu values for %zu scalar variables", nValues, nValueReferences);
        return fmi3Error;
    }
    for (i = 0; i < nValueReferences; i++) { /* check everything before changing anything */
        fmi3ValueReference vr = valueReferences[i];
        int kind = vr < N_VARIABLES ? causality[vr] : OUTPUT;
        if (kind != INPUT && !(kind == PARAMETER && (BEFORE_INIT_END & (1 << inst->mode)))) {
            log_message(inst, fmi3Error, "fmi3SetFloat64: value reference %u cannot be set in mode %d", vr,
                        (int)inst->mode);
            return fmi3Error;
        }
    }
    for (i = 0; i < nValueReferences; i++) inst->value[valueReferences[i]] = values[i];
    return fmi3OK;
}

/* This FMU has only Float64 variables: getting or setting another type succeeds only for no variables. */
static fmi3Status no_variables(fmi3Instance instance, const char *function, size_t nValueReferences) {
    if (!allowed(instance, function, ANY_MODE)) return fmi3Error;
    if (nValueReferences == 0) return fmi3OK;
    log_message((Instance *)instance, fmi3Error, "%s: this FMU has no variables of that type", function);
    return fmi3Error;
}

#define NO_GET(NAME, TYPE)                                                                                      \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    TYPE values[], size_t nValues) {                                                            \
        return no_variables(instance, #NAME, nValueReferences);                                                 \
    }
#define NO_SET(NAME, TYPE)                                                                                      \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    const TYPE values[], size_t nValues) {                                                      \
        return no_variables(instance, #NAME, nValueReferences);                                                 \
    }

NO_GET(fmi3GetFloat32, fmi3Float32)
NO_GET(fmi3GetInt8, fmi3Int8)
NO_GET(fmi3GetUInt8, fmi3UInt8)
NO_GET(fmi3GetInt16, fmi3Int16)
NO_GET(fmi3GetUInt16, fmi3UInt16)
NO_GET(fmi3GetInt32, fmi3Int32)
NO_GET(fmi3GetUInt32, fmi3UInt32)
NO_GET(fmi3GetInt64, fmi3Int64)
NO_GET(fmi3GetUInt64, fmi3UInt64)
NO_GET(fmi3GetBoolean, fmi3Boolean)
NO_GET(fmi3GetString, fmi3String)
NO_SET(fmi3SetFloat32, fmi3Float32)
NO_SET(fmi3SetInt8, fmi3Int8)
NO_SET(fmi3SetUInt8, fmi3UInt8)
NO_SET(fmi3SetInt16, fmi3Int16)
NO_SET(fmi3SetUInt16, fmi3UInt16)
NO_SET(fmi3SetInt32, fmi3Int32)
NO_SET(fmi3SetUInt32, fmi3UInt32)
NO_SET(fmi3SetInt64, fmi3Int64)
NO_SET(fmi3SetUInt64, fmi3UInt64)
NO_SET(fmi3SetBoolean, fmi3Boolean)
NO_SET(fmi3SetString, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    return no_variables(instance, "fmi3GetBinary", nValueReferences);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    return no_variables(instance, "fmi3SetBinary", nValueReferences);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[]) {
    return no_variables(instance, "fmi3GetClock", nValueReferences);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[]) {
    return no_variables(instance, "fmi3SetClock", nValueReferences);
}

/* ---- Variable dependencies (the modelDescription's ModelStructure has them) ---- */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    return unsupported(instance, "fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    return unsupported(instance, "fmi3GetVariableDependencies");
}

/* ---- FMU state: a copy of (time, x, v) ---- */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Instance *inst = (Instance *)instance;
    State *state;
    if (!CAN_GET_AND_SET_STATE) return unsupported(instance, "fmi3GetFMUState");
    if (!allowed(instance, "fmi3GetFMUState", ANY_MODE)) return fmi3Error;
    update_states(inst);
    state = *FMUState ? (State *)*FMUState : malloc(sizeof(State)); /* an existing state is overwritten */
    if (!state) return fmi3Error;
    state->time = inst->value[VR_time];
    state->x = inst->value[VR_x];
    state->v = inst->value[VR_v];
    *FMUState = state;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    Instance *inst = (Instance *)instance;
    const State *state = (const State *)FMUState;
    if (!CAN_GET_AND_SET_STATE) return unsupported(instance, "fmi3SetFMUState");
    if (!allowed(instance, "fmi3SetFMUState", ANY_MODE)) return fmi3Error;
    if (!state) {
        log_message(inst, fmi3Error, "fmi3SetFMUState: the state is NULL");
        return fmi3Error;
    }
    inst->value[VR_time] = state->time;
    inst->value[VR_x] = state->x;
    inst->value[VR_v] = state->v;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (!CAN_GET_AND_SET_STATE) return unsupported(instance, "fmi3FreeFMUState");
    if (!allowed(instance, "fmi3FreeFMUState", ANY_MODE)) return fmi3Error;
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    if (!CAN_SERIALIZE_STATE) return unsupported(instance, "fmi3SerializedFMUStateSize");
    if (!allowed(instance, "fmi3SerializedFMUStateSize", ANY_MODE)) return fmi3Error;
    *size = STATE_SIZE;
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    const State *state = (const State *)FMUState;
    double values[3];
    if (!CAN_SERIALIZE_STATE) return unsupported(instance, "fmi3SerializeFMUState");
    if (!allowed(instance, "fmi3SerializeFMUState", ANY_MODE)) return fmi3Error;
    if (!state || size < STATE_SIZE) {
        log_message((Instance *)instance, fmi3Error, "fmi3SerializeFMUState: no state, or a buffer of %zu < %zu bytes",
                    size, STATE_SIZE);
        return fmi3Error;
    }
    values[0] = state->time;
    values[1] = state->x;
    values[2] = state->v;
    memcpy(serializedState, values, STATE_SIZE);
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    double values[3];
    State *state;
    if (!CAN_SERIALIZE_STATE) return unsupported(instance, "fmi3DeserializeFMUState");
    if (!allowed(instance, "fmi3DeserializeFMUState", ANY_MODE)) return fmi3Error;
    if (size != STATE_SIZE) {
        log_message((Instance *)instance, fmi3Error, "fmi3DeserializeFMUState: %zu bytes, expected %zu", size,
                    STATE_SIZE);
        return fmi3Error;
    }
    state = *FMUState ? (State *)*FMUState : malloc(sizeof(State));
    if (!state) return fmi3Error;
    memcpy(values, serializedState, STATE_SIZE);
    state->time = values[0];
    state->x = values[1];
    state->v = values[2];
    *FMUState = state;
    return fmi3OK;
}

/* ---- Partial derivatives ---- */

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    return unsupported(instance, "fmi3GetDirectionalDerivative");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    return unsupported(instance, "fmi3GetAdjointDerivative");
}

/* ---- Configuration mode, clocks and discrete states: not in this FMU ---- */

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterConfigurationMode");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3ExitConfigurationMode");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[]) {
    return unsupported(instance, "fmi3GetIntervalDecimal");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    return unsupported(instance, "fmi3GetIntervalFraction");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[]) {
    return unsupported(instance, "fmi3GetShiftDecimal");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    return unsupported(instance, "fmi3GetShiftFraction");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[]) {
    return unsupported(instance, "fmi3SetIntervalDecimal");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[]) {
    return unsupported(instance, "fmi3SetIntervalFraction");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[]) {
    return unsupported(instance, "fmi3SetShiftDecimal");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[]) {
    return unsupported(instance, "fmi3SetShiftFraction");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    return unsupported(instance, "fmi3EvaluateDiscreteStates");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    return unsupported(instance, "fmi3UpdateDiscreteStates");
}

/* ---- Model Exchange: not offered by this FMU ---- */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterContinuousTimeMode");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    return unsupported(instance, "fmi3CompletedIntegratorStep");
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) { return unsupported(instance, "fmi3SetTime"); }

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    return unsupported(instance, "fmi3SetContinuousStates");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    return unsupported(instance, "fmi3GetContinuousStateDerivatives");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    return unsupported(instance, "fmi3GetEventIndicators");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    return unsupported(instance, "fmi3GetContinuousStates");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    return unsupported(instance, "fmi3GetNominalsOfContinuousStates");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    return unsupported(instance, "fmi3GetNumberOfEventIndicators");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    return unsupported(instance, "fmi3GetNumberOfContinuousStates");
}

/* ---- Co-Simulation ---- */

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterStepMode"); /* only after event mode, which this FMU does not have */
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues) {
    return unsupported(instance, "fmi3GetOutputDerivatives");
}

/* One symplectic Euler step (kick, then drift) from currentCommunicationPoint over communicationStepSize. */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    Instance *inst = (Instance *)instance;
    double *p, h = communicationStepSize;
    if (!allowed(instance, "fmi3DoStep", 1 << STEP)) return fmi3Error;
    p = inst->value;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = p[VR_time];
    if (!(h > 0.0)) {
        log_message(inst, fmi3Error, "fmi3DoStep: the step size %g is not positive", h);
        return fmi3Error;
    }
    if (currentCommunicationPoint >= p[VR_fail_at]) {
        log_message(inst, fmi3Error, "fmi3DoStep: the step starts at %.17g, at or after fail_at = %.17g",
                    currentCommunicationPoint, p[VR_fail_at]);
        return fmi3Error;
    }
    update_outputs(inst); /* a from the state and inputs at the start of the step */
    p[VR_v] = p[VR_v] + h * p[VR_a];
    p[VR_x] = p[VR_x] + h * p[VR_v];
    p[VR_time] = currentCommunicationPoint + h;
    *lastSuccessfulTime = p[VR_time];
    return fmi3OK;
}

/* ---- Scheduled Execution: not offered by this FMU ---- */

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    return unsupported(instance, "fmi3ActivateModelPartition");
}
