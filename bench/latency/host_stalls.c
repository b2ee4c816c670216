/* How late this host wakes a sleeping process: sleeps of 1 ms, back to back, for the given
 * seconds, and how much later than asked each one ended. A gateway waiting on a Modbus socket
 * or a PTY is woken the same way, so when sleeps here end milliseconds late (a VM whose host
 * takes its CPUs away, a host throttling a VM after heavy use), a latency tail of the same size
 * is the machine's, not the gateway's. bench/run-all runs it right before the latency bench.
 *
 *   host_stalls [SECONDS]     (default 5)
 * One line: sleeps, late > 0.5 / 1 / 2 ms, p99 and max lateness in us. */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static long long now_ns(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1000000000LL + t.tv_nsec;
}

static int by_value(const void* a, const void* b) {
  const long long x = *(const long long*)a, y = *(const long long*)b;
  return (x > y) - (x < y);
}

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? atof(argv[1]) : 5.0;
  if (!(seconds > 0) || seconds > 3600) {
    fprintf(stderr, "usage: host_stalls [SECONDS (0-3600)]\n");
    return 2;
  }
  const long capacity = (long)(seconds * 1000) + 1;
  long long* late = malloc(sizeof(long long) * (size_t)capacity);
  if (!late) return 1;
  long n = 0, over_half = 0, over_1 = 0, over_2 = 0;
  const long long end = now_ns() + (long long)(seconds * 1e9);
  for (long long before = now_ns(); before < end && n < capacity;) {
    const struct timespec ms = {0, 1000000};
    nanosleep(&ms, NULL);
    const long long after = now_ns();
    const long long l = after - before - 1000000;
    late[n++] = l;
    over_half += l > 500000;
    over_1 += l > 1000000;
    over_2 += l > 2000000;
    before = after;
  }
  qsort(late, (size_t)n, sizeof(long long), by_value);
  long at = (long)(0.99 * (double)n);
  if (at >= n) at = n - 1;
  const long long p99 = n > 0 ? late[at] : 0;
  printf(
      "host stalls: %ld sleeps of 1 ms in %.0f s; late > 0.5 ms %ld, > 1 ms %ld, > 2 ms %ld; "
      "late p99 %lld us, max %lld us\n",
      n, seconds, over_half, over_1, over_2, p99 / 1000, n ? late[n - 1] / 1000 : 0);
  free(late);
  return 0;
}
