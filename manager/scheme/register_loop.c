/* A generated macro-step loop (manager/scheme/compiled.py) run as a register program (register_loop.py): the loop's
   statements, translated once to three-address operations over an array of doubles (the loop's float names, its
   constants and its intermediate values), run here step after step. Each operation is one IEEE-754 double operation,
   as Python's float does it (compiled with -ffp-contract=off: nothing fused), so the registers hold what the Python
   loop's names hold, bit for bit. Where the left operand of a sum, difference or product is a NaN, it is the result:
   the hardware returns whichever NaN operand the compiler put first, CPython's specialized float operations and numpy
   the left one (CPython's generic float_add the right one: a NaN's sign is not Python's to give). Per step: the
   operations in order, STAMP storing the step's release time (CLOCK_MONOTONIC, Python's perf_counter_ns) in
   times[k]; then the row (the registers listed in row) stored in rows[k * width ...]. */
#include <time.h>

enum { ADD = 0, SUBTRACT = 1, MULTIPLY = 2, NEGATE = 3, COPY = 4, STAMP = 5, ADD_PRODUCT = 6 };

typedef struct {
    int code; /* one of the enum above */
    int target;
    int left;
    int right;
    int factor; /* ADD_PRODUCT: target = left + right * factor, the product rounded first, as Python's a + b * c */
} operation;

void register_loop_run(const operation *operations, long long n_operations, double *registers, const int *row,
                       long long width, long long steps, double *rows, long long *times) {
    struct timespec now;
    for (long long k = 0; k < steps; ++k) {
        for (long long i = 0; i < n_operations; ++i) {
            const operation *o = operations + i;
            if (o->code == STAMP) {
                clock_gettime(CLOCK_MONOTONIC, &now);
                times[k] = (long long)now.tv_sec * 1000000000LL + now.tv_nsec;
                continue;
            }
            const double left = registers[o->left];
            double right = registers[o->right], value;
            switch (o->code) {
            case ADD_PRODUCT:
                right = right != right ? right : right * registers[o->factor];
                value = left + right;
                break;
            case ADD: value = left + right; break;
            case SUBTRACT: value = left - right; break;
            case MULTIPLY: value = left * right; break;
            case NEGATE: value = -left; break;
            default: value = left; break; /* COPY */
            }
            registers[o->target] = left != left && (o->code <= MULTIPLY || o->code == ADD_PRODUCT) ? left : value;
        }
        double *out = rows + k * width;
        for (long long j = 0; j < width; ++j) out[j] = registers[row[j]];
    }
}
