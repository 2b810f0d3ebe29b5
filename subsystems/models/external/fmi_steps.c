/* One communication step of an FMI 2.0 or 3.0 Co-Simulation FMU in one call from Python (subsystems/models/external/
   fmi_steps.py): per micro-step the inputs set (fmi2SetReal, fmi3SetFloat64), then the step (fmi2DoStep, fmi3DoStep)
   at t = (start + j h) * 1e-9 s; at the end the outputs got (fmi2GetReal, fmi3GetFloat64). The same calls, with the
   same arguments and times, that would otherwise be one ctypes call each (subsystems/models/external/fmu.py,
   step_text), where each call cost about 3,700 instructions (benchmarks/bench_ffi.py). A status worse than a warning
   stops it, and so does an FMI 3.0 FMU that asks to terminate: the call (0 set, 1 step, 2 get) and its time are left
   in the struct, and the status is returned (TERMINATE when asked to terminate); else 0. The struct is passed as a
   void *: a register program calls these functions as it calls any native step (manager/scheme/register_loop.c). */
#include <stdbool.h>
#include <stddef.h>

#define TERMINATE (-1)

typedef int (*fmi2_set_real)(void *, const unsigned int *, size_t, const double *);
typedef int (*fmi2_do_step)(void *, double, double, int);
typedef int (*fmi2_get_real)(void *, const unsigned int *, size_t, double *);
typedef int (*fmi3_set_float64)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*fmi3_do_step)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef int (*fmi3_get_float64)(void *, const unsigned int *, size_t, double *, size_t);

typedef struct {
    void *set;  /* the FMU's functions, of the types above for its FMI version */
    void *do_step;
    void *get;
    void *instance;
    const unsigned int *inputs;
    size_t n_inputs;
    const double *u;
    const unsigned int *outputs;
    size_t n_outputs;
    double *y;
    long long h_ns;
    double h;
    long long micro_steps;
    long long failed_call;
    double failed_time;
} fmi_steps;

static int failed(fmi_steps *f, int status, long long call, double t) {
    f->failed_call = call;
    f->failed_time = t;
    return status;
}

static double micro_step_time(const fmi_steps *f, long long start_ns, long long j) {
    return (double)(start_ns + j * f->h_ns) * 1e-9;
}

int fmi2_steps_run(void *steps, long long start_ns) {
    fmi_steps *f = steps;
    int status;
    long long j;
    for (j = 0; j < f->micro_steps; j++) {
        double t = micro_step_time(f, start_ns, j);
        if (f->n_inputs) {
            status = ((fmi2_set_real)f->set)(f->instance, f->inputs, f->n_inputs, f->u);
            if (status > 1) return failed(f, status, 0, t);
        }
        status = ((fmi2_do_step)f->do_step)(f->instance, t, f->h, 0);
        if (status > 1) return failed(f, status, 1, t);
    }
    if (f->n_outputs) {
        status = ((fmi2_get_real)f->get)(f->instance, f->outputs, f->n_outputs, f->y);
        if (status > 1) return failed(f, status, 2, micro_step_time(f, start_ns, f->micro_steps));
    }
    return 0;
}

int fmi3_steps_run(void *steps, long long start_ns) {
    fmi_steps *f = steps;
    int status;
    long long j;
    bool event_handling_needed, terminate, early_return;
    double last_successful_time;
    for (j = 0; j < f->micro_steps; j++) {
        double t = micro_step_time(f, start_ns, j);
        if (f->n_inputs) {
            status = ((fmi3_set_float64)f->set)(f->instance, f->inputs, f->n_inputs, f->u, f->n_inputs);
            if (status > 1) return failed(f, status, 0, t);
        }
        terminate = false;
        status = ((fmi3_do_step)f->do_step)(f->instance, t, f->h, false, &event_handling_needed, &terminate,
                                            &early_return, &last_successful_time);
        if (status > 1) return failed(f, status, 1, t);
        if (terminate) return failed(f, TERMINATE, 1, t);
    }
    if (f->n_outputs) {
        status = ((fmi3_get_float64)f->get)(f->instance, f->outputs, f->n_outputs, f->y, f->n_outputs);
        if (status > 1) return failed(f, status, 2, micro_step_time(f, start_ns, f->micro_steps));
    }
    return 0;
}
