/* One communication step of an FMI 2.0 Co-Simulation FMU in one call from Python (subsystems/models/external/
   fmi2_steps.py): per micro-step fmi2SetReal of the inputs, then fmi2DoStep at t = (start + j h) * 1e-9 s; at the
   end fmi2GetReal of the outputs. The same calls, with the same arguments and times, that the generated loop's
   statements make one ctypes call each (subsystems/models/external/fmu.py, step_text), where each call cost about
   4,000 instructions (benchmarks/bench_ffi.py). A status worse than fmi2Warning stops it: the call (0 set, 1 doStep,
   2 get) and its time are left in the struct, and the status is returned; else 0. */
#include <stddef.h>

typedef int (*set_real_fn)(void *, const unsigned int *, size_t, const double *);
typedef int (*do_step_fn)(void *, double, double, int);
typedef int (*get_real_fn)(void *, const unsigned int *, size_t, double *);

typedef struct {
    set_real_fn set_real;
    do_step_fn do_step;
    get_real_fn get_real;
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
} fmi2_steps;

static int failed(fmi2_steps *f, int status, long long call, double t) {
    f->failed_call = call;
    f->failed_time = t;
    return status;
}

int fmi2_steps_run(fmi2_steps *f, long long start_ns) {
    int status;
    long long j;
    for (j = 0; j < f->micro_steps; j++) {
        double t = (double)(start_ns + j * f->h_ns) * 1e-9;
        if (f->n_inputs) {
            status = f->set_real(f->instance, f->inputs, f->n_inputs, f->u);
            if (status > 1) return failed(f, status, 0, t);
        }
        status = f->do_step(f->instance, t, f->h, 0);
        if (status > 1) return failed(f, status, 1, t);
    }
    if (f->n_outputs) {
        status = f->get_real(f->instance, f->outputs, f->n_outputs, f->y);
        if (status > 1) return failed(f, status, 2, (double)(start_ns + f->micro_steps * f->h_ns) * 1e-9);
    }
    return 0;
}
