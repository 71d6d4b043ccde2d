/* Publishes N frame-metadata messages through the C ABI, one a millisecond, each stamped
 * with the device clock just before it is sent: the C side of
 * `cargo bench -p dash2sim-examples --bench publisher_latency` (docs/benchmarks.md).
 *   latency_c PREFIX N */
#define _POSIX_C_SOURCE 200809L

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "dash2sim_camera.h"

int main(int argc, char **argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: latency_c PREFIX N\n");
    return 2;
  }
  int32_t status;
  d2s_publisher *camera = d2s_publisher_open(argv[1], false, &status);
  if (!camera) {
    fprintf(stderr, "latency_c: %s\n", d2s_last_error());
    return 1;
  }
  long n = atol(argv[2]);
  struct timespec pause = {0, 1000000L};
  for (long k = 1; k <= n; k++) {
    nanosleep(&pause, NULL);
    if (d2s_publish_frame(camera, (uint64_t)k, d2s_device_now_us(), 0) != D2S_OK) {
      fprintf(stderr, "latency_c: %s\n", d2s_last_error());
      return 1;
    }
  }
  nanosleep(&(struct timespec){0, 500000000L}, NULL);
  d2s_publisher_close(camera);
  return 0;
}
