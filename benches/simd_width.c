/* Does this CPU run 512-bit double arithmetic at twice the rate of 256-bit? (issue #25)
 *
 *     gcc -O2 -fno-tree-vectorize -ffp-contract=off benches/simd_width.c -o /tmp/simd_width
 *     /tmp/simd_width
 *
 * Twelve independent chains of a multiply and an add (no FMA, as most of the lanes' arithmetic
 * is), in ymm and then in zmm registers: enough chains that the loop is bound by the FP ports'
 * throughput, not by latency (a multiply and an add take 8 cycles on a 4-cycle core; two
 * ports need 16 operations in flight, twelve chains give 24). Each chain is its own named
 * variable so that it stays in a register: the earlier version kept them in an array, which
 * GCC loaded and stored every iteration, so it timed store-to-load forwarding, not the
 * arithmetic (docs/performance-history.md §31 corrects the §22 result it gave). Twelve chains and
 * two constants fit AVX2's 16 ymm registers.
 *
 * Equal times mean 512-bit ops deliver twice the flops; a zmm/ymm time of 2 means they deliver
 * none extra (a core that splits 512-bit ops into two halves). Check the loops with
 * `objdump -d /tmp/simd_width`: their vmulpd and vaddpd must have no memory operand. Not used
 * by the tests.
 */
#include <immintrin.h>
#include <stdio.h>
#include <time.h>

#define CHAINS 12

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

/* One step of all twelve chains: x = x·m + c for x in a0 … a11. */
#define STEP(MUL, ADD)                                                                       \
    a0 = ADD(MUL(a0, m), c); a1 = ADD(MUL(a1, m), c); a2 = ADD(MUL(a2, m), c);              \
    a3 = ADD(MUL(a3, m), c); a4 = ADD(MUL(a4, m), c); a5 = ADD(MUL(a5, m), c);              \
    a6 = ADD(MUL(a6, m), c); a7 = ADD(MUL(a7, m), c); a8 = ADD(MUL(a8, m), c);              \
    a9 = ADD(MUL(a9, m), c); a10 = ADD(MUL(a10, m), c); a11 = ADD(MUL(a11, m), c)

#define SUM(T) (T(a0) + T(a1) + T(a2) + T(a3) + T(a4) + T(a5) + T(a6) + T(a7) + T(a8) +     \
                T(a9) + T(a10) + T(a11))

__attribute__((target("avx2"))) static double first_ymm(__m256d v) { return v[0]; }

__attribute__((target("avx2"))) static double ymm(long n) {
    const __m256d m = _mm256_set1_pd(0.999999), c = _mm256_set1_pd(1e-7);
    __m256d a0 = _mm256_set1_pd(0), a1 = _mm256_set1_pd(1), a2 = _mm256_set1_pd(2),
            a3 = _mm256_set1_pd(3), a4 = _mm256_set1_pd(4), a5 = _mm256_set1_pd(5),
            a6 = _mm256_set1_pd(6), a7 = _mm256_set1_pd(7), a8 = _mm256_set1_pd(8),
            a9 = _mm256_set1_pd(9), a10 = _mm256_set1_pd(10), a11 = _mm256_set1_pd(11);
    for (long k = 0; k < n; k++) {
        STEP(_mm256_mul_pd, _mm256_add_pd);
    }
    return SUM(first_ymm);
}

__attribute__((target("avx512f"))) static double first_zmm(__m512d v) { return v[0]; }

__attribute__((target("avx512f"))) static double zmm(long n) {
    const __m512d m = _mm512_set1_pd(0.999999), c = _mm512_set1_pd(1e-7);
    __m512d a0 = _mm512_set1_pd(0), a1 = _mm512_set1_pd(1), a2 = _mm512_set1_pd(2),
            a3 = _mm512_set1_pd(3), a4 = _mm512_set1_pd(4), a5 = _mm512_set1_pd(5),
            a6 = _mm512_set1_pd(6), a7 = _mm512_set1_pd(7), a8 = _mm512_set1_pd(8),
            a9 = _mm512_set1_pd(9), a10 = _mm512_set1_pd(10), a11 = _mm512_set1_pd(11);
    for (long k = 0; k < n; k++) {
        STEP(_mm512_mul_pd, _mm512_add_pd);
    }
    return SUM(first_zmm);
}

int main(void) {
    if (!__builtin_cpu_supports("avx512f")) {
        printf("no AVX-512F on this CPU: nothing to compare\n");
        return 0;
    }
    const long n = 100000000;
    for (int round = 0; round < 3; round++) {
        double t0 = now();
        double sy = ymm(n);
        double ty = now() - t0;
        t0 = now();
        double sz = zmm(n);
        double tz = now() - t0;
        double ops = 2.0 * CHAINS * n; /* vector operations per loop */
        printf("ymm %.3f s (%.2f Gflop/s, %.3f ns per op)   zmm %.3f s (%.2f Gflop/s, %.3f ns "
               "per op)   zmm/ymm time %.2f   [checks %g %g]\n",
               ty, 4 * ops / ty / 1e9, ty / ops * 1e9, tz, 8 * ops / tz / 1e9,
               tz / ops * 1e9, tz / ty, sy, sz);
    }
    return 0;
}
