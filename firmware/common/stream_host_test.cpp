// Host-side driver for the unit tests of stream_plan.cpp (tests/firmware/test_stream_plan_host.py), built with
// g++. One stream per input line:
//   <n> <a_0> <d_0> ... <a_n-1> <d_n-1> <position> <periods> <v_1> ... <v_periods>
// (delays in DELTA units); plans periods 1..<periods> with those set-points and prints one line:
//   S <tick>:<dir> ... N <kind>:<value> ... E <count> <residual>
#include <stdio.h>
#include <stdlib.h>

#include "stream_plan.h"

static Planner planner;
static char steps[1 << 20];
static size_t steps_len;
static char notices[1 << 16];
static size_t notices_len;

void sp_emit_step(uint8_t, uint32_t tick, int8_t dir) {
  steps_len += (size_t)snprintf(steps + steps_len, sizeof steps - steps_len, " %lu:%d", (unsigned long)tick, dir);
}

void sp_notice(uint8_t kind, uint8_t, int32_t value) {
  notices_len +=
      (size_t)snprintf(notices + notices_len, sizeof notices - notices_len, " %u:%ld", kind, (long)value);
}

int main() {
  static char line[1 << 20];
  while (fgets(line, sizeof line, stdin)) {
    char *p = line, *end;
    sp_shaper.n = (uint8_t)strtol(p, &end, 10);
    p = end;
    for (uint8_t i = 0; i < sp_shaper.n; i++) {
      sp_shaper.a[i] = (int16_t)strtol(p, &end, 10);
      p = end;
      sp_shaper.d[i] = (uint16_t)strtol(p, &end, 10);
      p = end;
    }
    int16_t position = (int16_t)strtol(p, &end, 10);
    p = end;
    long periods = strtol(p, &end, 10);
    p = end;
    planner.start(&position);
    steps_len = notices_len = 0;
    steps[0] = notices[0] = 0;
    for (long k = 1; k <= periods; k++) {
      int16_t v = (int16_t)strtol(p, &end, 10);
      p = end;
      planner.plan_period((uint32_t)k, &v);
    }
    printf("S%s N%s E %d %ld\n", steps, notices, planner.ax[0].c, (long)planner.ax[0].r);
    fflush(stdout);
  }
  return 0;
}
