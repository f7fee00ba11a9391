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
#define SP_AXES RIG_AXES                    // each axis a streams within -rig_axis_release[a]..rig_axis_travel[a]
#define SP_MAX_IMPULSES 8
#define SP_DELAY_UNIT_US 16
// The set-point history of each axis (a power of two): period k reads the set-points of periods k - q - 1 ..
// k (q = delay / T), so the longest delay must stay under (SP_HIST - 1) periods. One axis: 128 (delays up to
// 1 s). Several axes: 64 per axis (the history of four axes shares its RAM with the programme table), delays
// up to 620 ms.
#if SP_AXES > 1
#define SP_HIST 64
#define SP_MAX_DELAY_US 620000L
#define SP_MAX_DELAY_TEXT "delay: 0 first, rising, 16 us units, <= 0.62 s"
#else
#define SP_HIST 128
#define SP_MAX_DELAY_US 1000000L
#define SP_MAX_DELAY_TEXT "delay: 0 first, rising, 16 us units, <= 1 s"
#endif

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
static_assert(SP_MAX_DELAY_US / 16 / SP_PERIOD + 1 < SP_HIST, "the longest delay needs more set-point history");

enum SpNotice : uint8_t { SP_NOTICE_SPEED = 1, SP_NOTICE_TRAVEL = 2 };

// Supplied by the user of the planner (the sketch, or the host test driver).
void sp_emit_step(uint8_t axis, uint32_t tick, int8_t dir);  // a step at `tick` (ticks from STREAM, mod 2^32)
void sp_notice(uint8_t kind, uint8_t axis, int32_t value);  // a clamp episode begins (value: period or position)

// The shaper, as loaded (kept apart from the stream's state: it stays loaded across streams and programmes).
struct SpShaper {
  uint8_t n;
  int16_t a[SP_MAX_IMPULSES];
  uint16_t d[SP_MAX_IMPULSES];   // delays in DELTA
  // derived at start(): delay = q periods + p DELTA
  uint8_t q[SP_MAX_IMPULSES];
  uint16_t p[SP_MAX_IMPULSES];
  uint8_t q_max;
  uint8_t n_offsets;
  uint16_t offsets[SP_MAX_IMPULSES + 1];  // 0 and the distinct p_i, increasing: where the period is cut
};

extern SpShaper sp_shaper;  // the loaded shaper (stream_plan.cpp)

// One axis's position and clamp episodes.
struct SpAxis {
  int16_t c;        // planned step count
  int32_t r;        // residual: exact position = c + r / 2^28
  uint8_t speed_this, speed_clamped, travel_clamped;
};

// The stream's state: every axis's position and set-point history. Every axis is shaped by the one shaper.
struct Planner {
  uint32_t period;  // the period being planned
  SpAxis ax[SP_AXES];
  int16_t hist[SP_AXES][SP_HIST];  // set-point of axis a in period j at [a][j % SP_HIST]

  // Prepares the shaper's derived tables and the state: axis a starts at positions[a], history zero.
  void start(const int16_t *positions);
  // Takes the set-points of period k (v[a] for axis a) and plans the steps of [(k + 1) T, (k + 2) T).
  void plan_period(uint32_t k, const int16_t *v);

 private:
  int16_t v_at(uint8_t a, uint32_t j) const { return hist[a][j & (SP_HIST - 1)]; }
  void plan_axis(uint8_t a, uint32_t k);
  void piece(uint8_t a, uint32_t tb, uint32_t te, int32_t s);
  void clamp_travel(uint8_t a);
};

// Checks one impulse as IMP receives it: 0 if acceptable, else 1 (amplitude) or 2 (delay).
// `previous_us` is the previous impulse's delay (-1 before the first).
uint8_t sp_check_impulse(uint8_t index, int32_t amp, int32_t delay_us, int32_t previous_us, uint8_t allow_negative);

#endif
