// The streaming planner (see stream_plan.h). Mirrors helpers/board/stream_reference.py's Planner line for line,
// once per axis.
#include "stream_plan.h"

SpShaper sp_shaper;

// ceil(32 * rem / s) for 0 <= rem < s: five steps of long division (no library division per step).
static uint8_t ceil_ticks(uint32_t rem, uint32_t s) {
  uint32_t x = rem;
  uint8_t q = 0;
  for (uint8_t i = 0; i < 5; i++) {
    x <<= 1;
    q <<= 1;
    if (x >= s) {
      x -= s;
      q |= 1;
    }
  }
  return (uint8_t)(q + (x ? 1 : 0));
}

void Planner::start(const int16_t *positions) {
  SpShaper &h = sp_shaper;
  h.q_max = 0;
  h.n_offsets = 0;
  h.offsets[h.n_offsets++] = 0;
  for (uint8_t i = 0; i < h.n; i++) {
    h.q[i] = (uint8_t)(h.d[i] / SP_PERIOD);
    h.p[i] = (uint16_t)(h.d[i] % SP_PERIOD);
    if (h.q[i] > h.q_max) h.q_max = h.q[i];
    // insert p[i] into the sorted list of distinct offsets
    uint8_t j = 0;
    while (j < h.n_offsets && h.offsets[j] < h.p[i]) j++;
    if (j < h.n_offsets && h.offsets[j] == h.p[i]) continue;
    for (uint8_t m = h.n_offsets; m > j; m--) h.offsets[m] = h.offsets[m - 1];
    h.offsets[j] = h.p[i];
    h.n_offsets++;
  }
  period = 0;
  for (uint8_t a = 0; a < SP_AXES; a++) {
    SpAxis &x = ax[a];
    x.c = positions[a];
    x.r = 0;
    x.speed_this = x.speed_clamped = x.travel_clamped = 0;
    for (uint16_t j = 0; j < SP_HIST; j++) hist[a][j] = 0;
  }
}

void Planner::clamp_travel(uint8_t a) {
  SpAxis &x = ax[a];
  x.r = 0;
  if (!x.travel_clamped) sp_notice(SP_NOTICE_TRAVEL, a, x.c);
  x.travel_clamped = 1;
}

void Planner::plan_period(uint32_t k, const int16_t *v) {
  period = k;
  for (uint8_t a = 0; a < SP_AXES; a++) {
    hist[a][k & (SP_HIST - 1)] = v[a];
    plan_axis(a, k);
  }
}

void Planner::plan_axis(uint8_t a, uint32_t k) {
  const SpShaper &h = sp_shaper;
  SpAxis &x = ax[a];
  x.speed_this = 0;
  uint32_t base = (k + 1) * (uint32_t)SP_PERIOD;
  int32_t s = 0;
  for (uint8_t i = 0; i < h.n; i++) s += (int32_t)h.a[i] * v_at(a, k - h.q[i] - (h.p[i] > 0 ? 1 : 0));
  for (uint8_t m = 0; m < h.n_offsets; m++) {
    uint16_t o = h.offsets[m];
    if (o > 0) {
      for (uint8_t i = 0; i < h.n; i++) {
        if (h.p[i] == o) s += (int32_t)h.a[i] * (int32_t)(v_at(a, k - h.q[i]) - v_at(a, k - h.q[i] - 1));
      }
    }
    uint16_t end = (m + 1 < h.n_offsets) ? h.offsets[m + 1] : SP_PERIOD;
    piece(a, base + o, base + end, s);
  }
  if (x.speed_this && !x.speed_clamped) sp_notice(SP_NOTICE_SPEED, a, (int32_t)k);
  x.speed_clamped = x.speed_this;
}

void Planner::piece(uint8_t a, uint32_t tb, uint32_t te, int32_t s) {
  SpAxis &x = ax[a];
  if (s > SP_S_MAX) {
    s = SP_S_MAX;
    x.speed_this = 1;
  } else if (s < -SP_S_MAX) {
    s = -SP_S_MAX;
    x.speed_this = 1;
  }
  // a step due exactly at the boundary (the exact position reached c +- 1 there)
  if (x.r >= SP_ONE) {
    x.c++;
    sp_emit_step(a, tb * SP_DELTA_TICKS, 1);
    x.r -= SP_ONE;
  } else if (x.r <= -SP_ONE) {
    x.c--;
    sp_emit_step(a, tb * SP_DELTA_TICKS, -1);
    x.r += SP_ONE;
  }
  if (s == 0) return;
  bool up = s > 0;
  uint32_t speed = (uint32_t)(up ? s : -s);
  int16_t limit = up ? (int16_t)rig_axis_travel[a] : -(int16_t)rig_axis_release[a];
  int8_t dir = up ? 1 : -1;
  int32_t rr = up ? x.r : -x.r;  // the residual in the direction of motion
  if (x.c == limit && rr == 0) {
    clamp_travel(a);
    return;
  }
  x.travel_clamped = 0;
  uint32_t dist = (uint32_t)((x.c == limit ? 0 : SP_ONE) - rr);  // > 0
  uint32_t q = dist / speed, rem = dist % speed;
  uint32_t q1 = (uint32_t)SP_ONE / speed, r1 = (uint32_t)SP_ONE % speed;
  uint32_t length = te - tb;
  while (q < length) {
    if (x.c == limit) {  // the event was reaching the limit itself
      clamp_travel(a);
      return;
    }
    x.c += dir;
    sp_emit_step(a, (tb + q) * SP_DELTA_TICKS + ceil_ticks(rem, speed), dir);
    if (x.c == limit) {  // reached the limit while still moving outward
      clamp_travel(a);
      return;
    }
    q += q1;
    rem += r1;
    if (rem >= speed) {
      rem -= speed;
      q++;
    }
  }
  int32_t theta = (x.c == limit) ? 0 : SP_ONE;
  rr = theta - (int32_t)(speed * (q - length) + rem);
  x.r = up ? rr : -rr;
}

uint8_t sp_check_impulse(uint8_t index, int32_t amp, int32_t delay_us, int32_t previous_us, uint8_t allow_negative) {
  if (amp > SP_AMP_MAX || amp < -SP_AMP_MAX || (amp < 0 && !allow_negative)) return 1;
  if (delay_us < 0 || delay_us > SP_MAX_DELAY_US || delay_us % SP_DELAY_UNIT_US != 0) return 2;
  if (index == 0 ? delay_us != 0 : delay_us <= previous_us) return 2;
  return 0;
}
