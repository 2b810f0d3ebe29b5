/* A generated macro-step loop (manager/scheme/compiled.py) run as a register program (register_loop.py): the loop's
   statements, translated once to three-address operations over an array of doubles (the loop's float names, its
   constants and its intermediate values), run here step after step. Each operation is one IEEE-754 double operation,
   as Python's float does it (compiled with -ffp-contract=off: nothing fused), so the registers hold what the Python
   loop's names hold, bit for bit. Where the left operand of a sum, difference or product is a NaN, it is the result:
   the hardware returns whichever NaN operand the compiler put first, CPython's specialized float operations and numpy
   the left one (CPython's generic float_add the right one: a NaN's sign is not Python's to give). Per step: the
   operations in order, STAMP storing the step's release time (CLOCK_MONOTONIC, Python's perf_counter_ns) in
   times[k], NATIVE making a subsystem's step as one call (natives[left]: an FMU's, subsystems/models/external/
   fmi_steps.c) with its inputs copied from the registers before it and its outputs into them after it, in a
   watched run marked on the watch's page as ModelWatch.marking marks a call (manager/bus/watchdog.py); then the
   row (the registers listed in row) stored in rows[k * width ...]. A native step that fails (returns a nonzero
   status) ends the run at that step, its row not stored: outcome[0] is its index in natives, outcome[1] the status.
   The run also ends after a step released more than budget_ns after the first (a slow model's steps: the caller
   sees an interrupt between runs; LLONG_MAX: no budget). Returns the number of steps whose rows were stored, and
   leaves it in outcome[2] with first_tick in outcome[3]: an interrupt that arrived during the run is raised as the
   call returns, before its caller has the returned number. */
#include <time.h>

enum { ADD = 0, SUBTRACT = 1, MULTIPLY = 2, NEGATE = 3, COPY = 4, STAMP = 5, ADD_PRODUCT = 6, NATIVE = 7 };
enum { SUBSYSTEM = 0, PHASE = 1, CALLS = 2, T_NS = 3, STEPPING = 2 }; /* the watch's slots, and its phase of a step */

typedef struct {
    int code; /* one of the enum above */
    int target;
    int left;
    int right;
    int factor; /* ADD_PRODUCT: target = left + right * factor, the product rounded first, as Python's a + b * c */
} operation;

typedef struct {
    int (*run)(void *argument, long long start_ns); /* the step from start_ns [ns]: 0, else the failure's status */
    void *argument;
    double *u; /* the step's inputs, copied from registers inputs[0 ... n_inputs - 1] before it */
    const int *inputs;
    long long n_inputs;
    const double *y; /* its outputs, copied to registers outputs[0 ... n_outputs - 1] after it */
    const int *outputs;
    long long n_outputs;
    volatile long long *marks; /* a watched run's page of slots, else NULL */
    long long mark;            /* the subsystem's number on it */
} native_step;

long long register_loop_run(const operation *operations, long long n_operations, double *registers, const int *row,
                            long long width, long long steps, double *rows, long long *times,
                            const native_step *natives, long long first_tick, long long tick_ns, long long budget_ns,
                            long long *outcome) {
    struct timespec now;
    outcome[3] = first_tick;
    for (long long k = 0; k < steps; ++k) {
        for (long long i = 0; i < n_operations; ++i) {
            const operation *o = operations + i;
            double left, right, value;
            switch (o->code) {
            case ADD_PRODUCT:
                left = registers[o->left];
                right = registers[o->right];
                value = left + (right != right ? right : right * registers[o->factor]);
                break;
            case ADD: left = registers[o->left]; value = left + registers[o->right]; break;
            case SUBTRACT: left = registers[o->left]; value = left - registers[o->right]; break;
            case MULTIPLY: left = registers[o->left]; value = left * registers[o->right]; break;
            case NEGATE: registers[o->target] = -registers[o->left]; continue;
            case COPY: registers[o->target] = registers[o->left]; continue;
            case STAMP:
                clock_gettime(CLOCK_MONOTONIC, &now);
                times[k] = (long long)now.tv_sec * 1000000000LL + now.tv_nsec;
                continue;
            default: { /* NATIVE */
                const native_step *s = natives + o->left;
                const long long start_ns = (first_tick + k) * tick_ns;
                for (long long j = 0; j < s->n_inputs; ++j) s->u[j] = registers[s->inputs[j]];
                if (s->marks) {
                    s->marks[SUBSYSTEM] = s->mark;
                    s->marks[PHASE] = STEPPING;
                    s->marks[T_NS] = start_ns;
                    s->marks[CALLS] += 1;
                }
                const int status = s->run(s->argument, start_ns);
                if (status) { /* the mark is left, as a step that raises leaves it */
                    outcome[0] = o->left;
                    outcome[1] = status;
                    return outcome[2] = k;
                }
                if (s->marks) s->marks[SUBSYSTEM] = -1;
                for (long long j = 0; j < s->n_outputs; ++j) registers[s->outputs[j]] = s->y[j];
                continue;
            }
            }
            registers[o->target] = left != left ? left : value; /* a sum, difference or product */
        }
        double *out = rows + k * width;
        for (long long j = 0; j < width; ++j) out[j] = registers[row[j]];
        if (times[k] - times[0] > budget_ns) return outcome[2] = k + 1;
    }
    return outcome[2] = steps;
}
