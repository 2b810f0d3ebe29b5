/* The "peer pair" of the interop tests: paper 000's damped two-mass oscillator as two FMI 2.0
   Co-Simulation FMUs, written for these tests alone (nothing in zencosim builds or reads this file).

   Compiled twice from this one source (tests/interop/peer_pair.py), with -DPEER_MASS=1 or -DPEER_MASS=2;
   peer_table.h, written beside the build by peer_pair.py from its table of variables, gives VR_<name>,
   N_VARIABLES, START_VALUES, IS_INPUT and GUID.

   mass1 (-DPEER_MASS=1): mass 1 with its spring k and damper c to ground, and the coupling spring kc
   and damper cc between mass 1 and mass 2, whose motion arrives as the inputs x2_in, v2_in:

       fc = kc*(x1 - x2_in) + cc*(v1 - v2_in)    the force of the coupling element on mass 2
       a1 = (-k*x1 - c*v1 - fc) / m              mass 1 feels the reaction -fc

   mass2 (-DPEER_MASS=2): mass 2 with its spring k and damper c to ground; the input fc_in is applied
   with +:

       a2 = (-k*x2 - c*v2 + fc_in) / m

   Variants (tests/interop/peer_pair.py BUILD): -DPEER_OWN_FORCE (mass1) outputs f1 = -fc, the force of the
   coupling element on mass 1 itself, instead of fc; -DPEER_X_MM (mass2) outputs x2 in mm (x2 * 1000), its
   state and x0 staying in m; -DPEER_EXIT_AT=<t> (mass2) ends the process with exit(0) in the first doStep
   from time t on, as a model with a fatal fault may.

   Every doStep(t, h) is one symplectic Euler step over h (kick, then drift): v += h*a; x += h*v, with
   a from the state and the inputs at the start of the step. x and v start at the parameters x0 and v0
   when initialization mode is exited. fc is a direct-feedthrough output: fmi2GetReal computes it from
   the current state and inputs. Functions that do not apply to this model return fmi2Error. */

#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "peer_table.h"

#if PEER_MASS == 1
#define VR_X VR_x1
#define VR_V VR_v1
#elif PEER_MASS == 2
#define VR_X VR_x2
#define VR_V VR_v2
#else
#error "compile with -DPEER_MASS=1 or -DPEER_MASS=2"
#endif

typedef enum { INSTANTIATED, INITIALIZATION, STEP, TERMINATED } Mode;

typedef struct {
    double value[N_VARIABLES]; /* by value reference */
    Mode mode;
    const fmi2CallbackFunctions *functions;
    char *name;
} Instance;

static fmi2Status fail(fmi2Component c, const char *message) {
    Instance *inst = (Instance *)c;
    if (inst && inst->functions && inst->functions->logger)
        inst->functions->logger(inst->functions->componentEnvironment, inst->name, fmi2Error, "logStatusError",
                                message);
    return fmi2Error;
}

/* Before initialization mode is exited the state follows its start parameters. */
static void follow_start(Instance *inst) {
    if (inst->mode == INSTANTIATED || inst->mode == INITIALIZATION) {
        inst->value[VR_X] = inst->value[VR_x0];
        inst->value[VR_V] = inst->value[VR_v0];
    }
}

/* The acceleration of this FMU's mass (and, for mass1, the output fc) from the state and inputs. */
static double acceleration(Instance *inst) {
    double *p = inst->value, x, v;
    follow_start(inst);
    x = p[VR_X];
    v = p[VR_V];
#if PEER_MASS == 1
    double fc = p[VR_kc] * (x - p[VR_x2_in]) + p[VR_cc] * (v - p[VR_v2_in]);
#ifdef PEER_OWN_FORCE
    p[VR_f1] = -fc;
#else
    p[VR_fc] = fc;
#endif
    return (-p[VR_k] * x - p[VR_c] * v - fc) / p[VR_m];
#else
    return (-p[VR_k] * x - p[VR_c] * v + p[VR_fc_in]) / p[VR_m];
#endif
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    return c ? fmi2OK : fmi2Error;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    const double start[N_VARIABLES] = START_VALUES;
    Instance *inst;
    if (fmuType != fmi2CoSimulation || !fmuGUID || strcmp(fmuGUID, GUID) != 0) return NULL;
    inst = calloc(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->name = malloc(strlen(instanceName ? instanceName : "") + 1);
    if (!inst->name) {
        free(inst);
        return NULL;
    }
    strcpy(inst->name, instanceName ? instanceName : "");
    inst->functions = functions;
    inst->mode = INSTANTIATED;
    memcpy(inst->value, start, sizeof start);
    follow_start(inst);
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
    if (!c || ((Instance *)c)->mode != INSTANTIATED) return fail(c, "fmi2SetupExperiment: not instantiated");
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    if (!c || ((Instance *)c)->mode != INSTANTIATED) return fail(c, "fmi2EnterInitializationMode: not instantiated");
    ((Instance *)c)->mode = INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!inst || inst->mode != INITIALIZATION) return fail(c, "fmi2ExitInitializationMode: not initializing");
    if (!(inst->value[VR_m] > 0.0)) return fail(c, "fmi2ExitInitializationMode: the mass m must be positive");
    follow_start(inst);
    inst->mode = STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    if (!c) return fmi2Error;
    ((Instance *)c)->mode = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = (Instance *)c;
    const double start[N_VARIABLES] = START_VALUES;
    if (!inst) return fmi2Error;
    memcpy(inst->value, start, sizeof start);
    inst->mode = INSTANTIATED;
    follow_start(inst);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    size_t i;
    if (!inst) return fmi2Error;
    acceleration(inst); /* brings the state (before initialization) and fc up to date */
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= N_VARIABLES) return fail(c, "fmi2GetReal: unknown value reference");
        value[i] = inst->value[vr[i]];
#ifdef PEER_X_MM
        if (vr[i] == VR_x2) value[i] *= 1000.0;
#endif
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    const int is_input[N_VARIABLES] = IS_INPUT;
    size_t i;
    if (!inst || inst->mode == TERMINATED) return fail(c, "fmi2SetReal: no instance, or terminated");
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= N_VARIABLES) return fail(c, "fmi2SetReal: unknown value reference");
        if (is_input[vr[i]] < 0 || (is_input[vr[i]] == 0 && inst->mode == STEP))
            return fail(c, "fmi2SetReal: only inputs, and parameters before initialization ends, can be set");
    }
    for (i = 0; i < nvr; i++) inst->value[vr[i]] = value[i];
    return fmi2OK;
}

static fmi2Status none(fmi2Component c, size_t nvr) {
    return c && nvr == 0 ? fmi2OK : fail(c, "this FMU has only Real variables");
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    return none(c, nvr);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    return none(c, nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    return none(c, nvr);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    return none(c, nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    return none(c, nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    return none(c, nvr);
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) { return fail(c, "no FMU state"); }

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) { return fail(c, "no FMU state"); }

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) { return fail(c, "no FMU state"); }

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    return fail(c, "no FMU state");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    return fail(c, "no FMU state");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    return fail(c, "no FMU state");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    return fail(c, "no directional derivatives");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    return fail(c, "no input derivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    return fail(c, "no output derivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *inst = (Instance *)c;
    double a, h = communicationStepSize;
    if (!inst || inst->mode != STEP) return fail(c, "fmi2DoStep: not initialized");
    if (!(h > 0.0)) return fail(c, "fmi2DoStep: the step size is not positive");
#ifdef PEER_EXIT_AT
    if (currentCommunicationPoint >= PEER_EXIT_AT) exit(0);
#endif
    a = acceleration(inst);
    inst->value[VR_V] = inst->value[VR_V] + h * a;
    inst->value[VR_X] = inst->value[VR_X] + h * inst->value[VR_V];
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return fail(c, "fmi2CancelStep: doStep never pends"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    return fail(c, "fmi2GetStatus: doStep never pends");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    return fail(c, "fmi2GetRealStatus: not supported");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    return fail(c, "fmi2GetIntegerStatus: not supported");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (!c || s != fmi2Terminated) return fail(c, "fmi2GetBooleanStatus: only fmi2Terminated");
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    return fail(c, "fmi2GetStringStatus: not supported");
}
