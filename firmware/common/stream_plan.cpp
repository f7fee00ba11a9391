// The streaming planner (see stream_plan.h). Mirrors helpers/board/stream_reference.py's Planner line for line.
#include "stream_plan.h"

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

void Planner::start(int16_t position) {
  q_max = 0;
  n_offsets = 0;
  offsets[n_offsets++] = 0;
  for (uint8_t i = 0; i < n; i++) {
    q[i] = (uint8_t)(d[i] / SP_PERIOD);
    p[i] = (uint16_t)(d[i] % SP_PERIOD);
    if (q[i] > q_max) q_max = q[i];
    // insert p[i] into the sorted list of distinct offsets
    uint8_t j = 0;
    while (j < n_offsets && offsets[j] < p[i]) j++;
    if (j < n_offsets && offsets[j] == p[i]) continue;
    for (uint8_t m = n_offsets; m > j; m--) offsets[m] = offsets[m - 1];
    offsets[j] = p[i];
    n_offsets++;
  }
  c = position;
  r = 0;
  period = 0;
  speed_this = speed_clamped = travel_clamped = 0;
  for (uint16_t j = 0; j < SP_HIST; j++) hist[j] = 0;
}

void Planner::emit(uint32_t tick, int8_t dir) {
  c += dir;
  sp_emit_step(tick, dir);
}

void Planner::clamp_travel() {
  r = 0;
  if (!travel_clamped) sp_notice(SP_NOTICE_TRAVEL, c);
  travel_clamped = 1;
}

void Planner::plan_period(uint32_t k, int16_t v) {
  hist[k & (SP_HIST - 1)] = v;
  period = k;
  speed_this = 0;
  uint32_t base = (k + 1) * (uint32_t)SP_PERIOD;
  int32_t s = 0;
  for (uint8_t i = 0; i < n; i++) s += (int32_t)a[i] * v_at(k - q[i] - (p[i] > 0 ? 1 : 0));
  for (uint8_t m = 0; m < n_offsets; m++) {
    uint16_t o = offsets[m];
    if (o > 0) {
      for (uint8_t i = 0; i < n; i++) {
        if (p[i] == o) s += (int32_t)a[i] * (int32_t)(v_at(k - q[i]) - v_at(k - q[i] - 1));
      }
    }
    uint16_t end = (m + 1 < n_offsets) ? offsets[m + 1] : SP_PERIOD;
    piece(base + o, base + end, s);
  }
  if (speed_this && !speed_clamped) sp_notice(SP_NOTICE_SPEED, (int32_t)k);
  speed_clamped = speed_this;
}

void Planner::piece(uint32_t tb, uint32_t te, int32_t s) {
  if (s > SP_S_MAX) {
    s = SP_S_MAX;
    speed_this = 1;
  } else if (s < -SP_S_MAX) {
    s = -SP_S_MAX;
    speed_this = 1;
  }
  // a step due exactly at the boundary (the exact position reached c +- 1 there)
  if (r >= SP_ONE) {
    emit(tb * SP_DELTA_TICKS, 1);
    r -= SP_ONE;
  } else if (r <= -SP_ONE) {
    emit(tb * SP_DELTA_TICKS, -1);
    r += SP_ONE;
  }
  if (s == 0) return;
  bool up = s > 0;
  uint32_t speed = (uint32_t)(up ? s : -s);
  int16_t limit = up ? SP_TRAVEL_MAX : 0;
  int8_t dir = up ? 1 : -1;
  int32_t rr = up ? r : -r;  // the residual in the direction of motion
  if (c == limit && rr == 0) {
    clamp_travel();
    return;
  }
  travel_clamped = 0;
  uint32_t dist = (uint32_t)((c == limit ? 0 : SP_ONE) - rr);  // > 0
  uint32_t q = dist / speed, rem = dist % speed;
  uint32_t q1 = (uint32_t)SP_ONE / speed, r1 = (uint32_t)SP_ONE % speed;
  uint32_t length = te - tb;
  while (q < length) {
    if (c == limit) {  // the event was reaching the limit itself
      clamp_travel();
      return;
    }
    emit((tb + q) * SP_DELTA_TICKS + ceil_ticks(rem, speed), dir);
    if (c == limit) {  // reached the limit while still moving outward
      clamp_travel();
      return;
    }
    q += q1;
    rem += r1;
    if (rem >= speed) {
      rem -= speed;
      q++;
    }
  }
  int32_t theta = (c == limit) ? 0 : SP_ONE;
  rr = theta - (int32_t)(speed * (q - length) + rem);
  r = up ? rr : -rr;
}

uint8_t sp_check_impulse(uint8_t index, int32_t amp, int32_t delay_us, int32_t previous_us, uint8_t allow_negative) {
  if (amp > SP_AMP_MAX || amp < -SP_AMP_MAX || (amp < 0 && !allow_negative)) return 1;
  if (delay_us < 0 || delay_us > SP_MAX_DELAY_US || delay_us % SP_DELAY_UNIT_US != 0) return 2;
  if (index == 0 ? delay_us != 0 : delay_us <= previous_us) return 2;
  return 0;
}
