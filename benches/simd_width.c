/* Does this CPU run 512-bit double arithmetic at twice the rate of 256-bit? (issue #25)
 *
 *     gcc -O2 -fno-tree-vectorize -ffp-contract=off benches/simd_width.c -o /tmp/simd_width
 *     /tmp/simd_width
 *
 * Sixteen independent chains of a multiply and an add (no FMA, as the lanes compute), in ymm
 * and then in zmm registers: enough chains that the loop is bound by the FP ports' throughput,
 * not by latency. Equal times mean 512-bit ops deliver twice the flops; a zmm/ymm time of
 * 2 means they deliver none extra (a core that splits 512-bit ops into two halves).
 * docs/performance.md §22 has the result on the test machine. Not used by the tests.
 */
#include <immintrin.h>
#include <stdio.h>
#include <time.h>

#define CHAINS 16

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

__attribute__((target("avx2"))) static double ymm(long n) {
    __m256d a[CHAINS];
    const __m256d m = _mm256_set1_pd(0.999999), c = _mm256_set1_pd(1e-7);
    for (int i = 0; i < CHAINS; i++) a[i] = _mm256_set1_pd(i);
    for (long k = 0; k < n; k++)
        for (int i = 0; i < CHAINS; i++) a[i] = _mm256_add_pd(_mm256_mul_pd(a[i], m), c);
    double s = 0, t[4];
    for (int i = 0; i < CHAINS; i++) {
        _mm256_storeu_pd(t, a[i]);
        s += t[0] + t[3];
    }
    return s;
}

__attribute__((target("avx512f"))) static double zmm(long n) {
    __m512d a[CHAINS];
    const __m512d m = _mm512_set1_pd(0.999999), c = _mm512_set1_pd(1e-7);
    for (int i = 0; i < CHAINS; i++) a[i] = _mm512_set1_pd(i);
    for (long k = 0; k < n; k++)
        for (int i = 0; i < CHAINS; i++) a[i] = _mm512_add_pd(_mm512_mul_pd(a[i], m), c);
    double s = 0, t[8];
    for (int i = 0; i < CHAINS; i++) {
        _mm512_storeu_pd(t, a[i]);
        s += t[0] + t[7];
    }
    return s;
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
        double flops = 2.0 * CHAINS * n;
        printf("ymm %.3f s (%.2f Gflop/s)   zmm %.3f s (%.2f Gflop/s)   zmm/ymm time %.2f   "
               "[checks %g %g]\n",
               ty, 4 * flops / ty / 1e9, tz, 8 * flops / tz / 1e9, tz / ty, sy, sz);
    }
    return 0;
}
