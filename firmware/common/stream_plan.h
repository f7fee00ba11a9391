// The stepper board's streaming input shaper: plans the steps of one control period at a time (PROTOCOL.md,
// "Streaming"). Board-independent integer arithmetic, also compiled for the host: helpers/board/stream_reference.py is the
// same algorithm in Python and the tests compare the two tick for tick.
//
// Units: timer tick 0.5 us; DELTA = 32 ticks (16 us), the unit of delays and the time base of velocities;
// control period = 625 DELTA (10 ms). Set-point v: 2^-16 step per DELTA. Amplitude a: 2^-12 (4096 = 1).
// Shaped velocity S = sum a_i v(t - d_i): 2^-28 step per DELTA. Position: count c plus residual r (2^-28 step),
// exact at every DELTA boundary (nothing is ever rounded); a step is issued at the first tick at or after the
// exact instant the position reaches c + 1 (up) or c - 1 (down).
#ifndef FIRMWARE_COMMON_STREAM_PLAN_H
#define FIRMWARE_COMMON_STREAM_PLAN_H

#include <stdint.h>

#include "rig_config.h"

#define SP_DELTA_TICKS 32
#define SP_PERIOD 625                       // DELTA per control period
#define SP_PERIOD_TICKS 20000U              // 10 ms
#define SP_ONE (1L << 28)                   // one step in residual units
#define SP_AMP_ONE 4096                     // amplitude 1.0
#define SP_AMP_MAX 16384                    // |a| <= 4.0
// The speed limit from the rig's shortest step interval: |v| <= 2^20 / RIG_MIN_INTERVAL_US (set-point units of
// 2^-16 step per 16 us), i.e. 1640 for 639 us (1564.0 steps/s, a step every 639.375 us).
#define SP_V_MAX ((int16_t)((1L << 20) / RIG_MIN_INTERVAL_US))
#define SP_S_MAX ((int32_t)SP_V_MAX * 4096L)  // speed limit on the shaped output
#define SP_TRAVEL_MAX ((int16_t)rig_axis_travel[0])  // streams drive axis 0 (its travel from the rig config)
#define SP_MAX_IMPULSES 8
#define SP_DELAY_UNIT_US 16
#define SP_MAX_DELAY_US 1000000L
#define SP_HIST 128                         // set-point history (a power of two > 100 + 2 periods)

// The fixed-point ranges (PROTOCOL.md "Fixed point") hold for every rig config the contract allows:
// the shaped sum of SP_MAX_IMPULSES impulses of |a| <= SP_AMP_MAX on |v| <= SP_V_MAX fits an int32; the clamped
// speed moves less than one step per DELTA (one crossing per DELTA at most); a 10 ms period holds at most
// 32 steps (the stepper's step queue holds two periods: 32 steps, or 64 on a rig finer than 16 a period).
static_assert((1L << 20) / RIG_MIN_INTERVAL_US <= 32767, "SP_V_MAX must fit an int16");
static_assert((int64_t)((1L << 20) / RIG_MIN_INTERVAL_US) * SP_AMP_MAX * SP_MAX_IMPULSES < (1LL << 31),
              "the shaped sum would overflow int32");
static_assert((int64_t)((1L << 20) / RIG_MIN_INTERVAL_US) * SP_AMP_ONE < SP_ONE,
              "the speed limit must stay under one step per DELTA");
static_assert(10000L / RIG_MIN_INTERVAL_US + 1 <= 32, "more than 32 steps per control period");

enum SpNotice : uint8_t { SP_NOTICE_SPEED = 1, SP_NOTICE_TRAVEL = 2 };

// Supplied by the user of the planner (the sketch, or the host test driver).
void sp_emit_step(uint32_t tick, int8_t dir);          // a step at `tick` (timer ticks from STREAM, mod 2^32)
void sp_notice(uint8_t kind, int32_t value);           // a clamp episode begins (value: period or position)

struct Planner {
  // the shaper, as loaded
  uint8_t n;
  int16_t a[SP_MAX_IMPULSES];
  uint16_t d[SP_MAX_IMPULSES];   // delays in DELTA
  // derived at start(): delay = q periods + p DELTA
  uint8_t q[SP_MAX_IMPULSES];
  uint16_t p[SP_MAX_IMPULSES];
  uint8_t q_max;
  uint8_t n_offsets;
  uint16_t offsets[SP_MAX_IMPULSES + 1];  // 0 and the distinct p_i, increasing: where the period is cut
  // state
  int16_t c;        // planned step count
  int32_t r;        // residual: exact position = c + r / 2^28
  uint32_t period;  // the period being planned
  uint8_t speed_this, speed_clamped, travel_clamped;
  int16_t hist[SP_HIST];  // set-point of period j at [j % SP_HIST]

  // Prepares the derived tables and the state: the stream starts at `position`, history zero.
  void start(int16_t position);
  // Takes the set-point of period k and plans the steps of [(k + 1) T, (k + 2) T).
  void plan_period(uint32_t k, int16_t v);

 private:
  int16_t v_at(uint32_t j) const { return hist[j & (SP_HIST - 1)]; }
  void piece(uint32_t tb, uint32_t te, int32_t s);
  void emit(uint32_t tick, int8_t dir);
  void clamp_travel();
};

// Checks one impulse as IMP receives it: 0 if acceptable, else 1 (amplitude) or 2 (delay).
// `previous_us` is the previous impulse's delay (-1 before the first).
uint8_t sp_check_impulse(uint8_t index, int32_t amp, int32_t delay_us, int32_t previous_us, uint8_t allow_negative);

#endif
