/* The machine's limits for one core, against which drape's step is measured
 * (scripts/machine_limits.py compiles this with the system's cc -O3 -march=native
 * and runs it; BENCHMARKS.md, "How far the step is from the machine's limits").
 *
 *   triad   STREAM's triad a[i] = b[i] + s c[i] over three arrays of n doubles each
 *           (n * 8 B each, much larger than the last-level cache), best of `repeat`
 *           passes (each timed in CPU time, as drape's report is); GB/s counts 24 B per element as STREAM does (the write-allocate
 *           read of a[] is a further 8 B the memory moves but STREAM does not count).
 *   peak    double-precision FMA rate of one core: CHAINS independent chains of
 *           acc = acc * m + a on vectors of the widest width -march=native gives
 *           (GCC vector extensions), enough chains to cover the FMA latency on every
 *           FMA pipe; 2 flops per lane per FMA; best of 5.
 *   scalar  the same on scalar doubles (fma()): the peak of code that is not
 *           vectorised, as drape's force loop mostly is not.
 *
 * Standalone C (no PETSc): `machine_limits [n [repeat]]` prints one "name value"
 * line per figure. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#if defined(__AVX512F__)
  #define LANES 8
#elif defined(__AVX__)
  #define LANES 4
#else
  #define LANES 2
#endif
typedef double vec __attribute__((vector_size(8 * LANES)));

#define CHAINS 16
#define FMA_ITS 20000000L

/* CPU time of this process, s: time the scheduler gives another job does not count */
static double Now(void)
{
  struct timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return (double) t.tv_sec + 1e-9 * (double) t.tv_nsec;
}

/* The best time of `repeat` triads over n elements. */
static double Triad(long n, int repeat, double *checksum)
{
  double *a = aligned_alloc(64, (size_t) n * sizeof(double)), *b = aligned_alloc(64, (size_t) n * sizeof(double)), *c = aligned_alloc(64, (size_t) n * sizeof(double));
  double  best = 1e30;
  const double s = 3.0;

  if (!a || !b || !c) {
    fprintf(stderr, "machine_limits: cannot allocate 3 x %ld doubles\n", n);
    exit(1);
  }
  for (long i = 0; i < n; i++) {
    a[i] = 0;
    b[i] = 1;
    c[i] = 2;
  }
  for (int r = 0; r < repeat; r++) {
    const double t0 = Now();
    for (long i = 0; i < n; i++) a[i] = b[i] + s * c[i];
    const double t = Now() - t0;
    if (t < best) best = t;
    b[r % n] += a[(r * 7919L) % n] * 1e-300; /* the passes depend on each other */
  }
  *checksum = a[n / 2] + b[n / 3];
  free(a);
  free(b);
  free(c);
  return best;
}

/* Seconds for `its` iterations of CHAINS independent vector FMA chains. */
static double PeakVector(long its, double m, double add, double *checksum)
{
  vec acc[CHAINS], mv, av;
  for (int l = 0; l < LANES; l++) {
    mv[l] = m;
    av[l] = add;
  }
  for (int k = 0; k < CHAINS; k++)
    for (int l = 0; l < LANES; l++) acc[k][l] = 1.0 + 1e-3 * (k * LANES + l);
  const double t0 = Now();
  for (long i = 0; i < its; i++)
    for (int k = 0; k < CHAINS; k++) acc[k] = acc[k] * mv + av; /* contracted to FMA by -ffp-contract=fast, GCC's default */
  const double t = Now() - t0;
  double       sum = 0;
  for (int k = 0; k < CHAINS; k++)
    for (int l = 0; l < LANES; l++) sum += acc[k][l];
  *checksum = sum;
  return t;
}

/* Not vectorised: GCC would otherwise pack the independent chains into vectors. */
__attribute__((optimize("no-tree-vectorize", "no-tree-slp-vectorize"))) static double PeakScalar(long its, double m, double add, double *checksum)
{
  double acc[CHAINS];
  for (int k = 0; k < CHAINS; k++) acc[k] = 1.0 + 1e-3 * k;
  const double t0 = Now();
  for (long i = 0; i < its; i++)
    for (int k = 0; k < CHAINS; k++) acc[k] = fma(acc[k], m, add);
  const double t = Now() - t0;
  double       sum = 0;
  for (int k = 0; k < CHAINS; k++) sum += acc[k];
  *checksum = sum;
  return t;
}

int main(int argc, char **argv)
{
  const long   n      = argc > 1 ? atol(argv[1]) : 1L << 25;
  const int    repeat = argc > 2 ? atoi(argv[2]) : 10;
  const long   its    = argc > 3 ? atol(argv[3]) : FMA_ITS;
  const double m = 1.0 - 1e-9 * (argc > 0), add = 1e-9 * (argc > 0); /* not known at compile time */
  double       ck1, ck2, ck3, tv = 1e30, ts = 1e30;

  if (n < 1 || repeat < 1 || its < 1) {
    fprintf(stderr, "machine_limits: usage: machine_limits [n >= 1 [repeat >= 1 [fma_iterations >= 1]]]\n");
    return 1;
  }
  const double tt = Triad(n, repeat, &ck1);
  for (int r = 0; r < 5; r++) { /* best of five: a busy neighbour only slows a pass */
    const double a = PeakVector(its, m, add, &ck2), b = PeakScalar(its / LANES, m, add, &ck3);
    if (a < tv) tv = a;
    if (b < ts) ts = b;
  }
  printf("triad_array_mb %.1f\n", n * 8.0 / 1e6);
  printf("triad_gb_per_s %.2f\n", 24.0 * n / tt / 1e9);
  printf("fma_lanes %d\n", LANES);
  printf("peak_gflop_per_s %.2f\n", 2.0 * LANES * CHAINS * its / tv / 1e9);
  printf("scalar_gflop_per_s %.2f\n", 2.0 * CHAINS * (its / LANES) / ts / 1e9);
  printf("checksum %g\n", ck1 + ck2 + ck3);
  return 0;
}
