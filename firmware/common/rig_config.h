// The rig's build-time configuration: both sketches include this header, which includes the one the build
// names (make -C firmware RIG_CONFIG=path/to/header.h, or RIG=rigfile to generate it), by default
// rig_config_paper.h (the paper's one-tendon rig). Then the fixed macro contract is checked here, so that a
// header generated from a rig file (python -m helpers.rigfile.firmware_header RIGFILE -o OUT.h) that misses a
// macro or holds an out-of-range value stops the build with one line naming it.
//
// The contract (every macro required):
//   RIG_HASH                 "8 hex chars": the rig file's hash, reported in HELLO and PONG (version+hash)
//   RIG_NAME                 "paper": the rig's name (for people; not sent)
//   RIG_AXES                 1-4 steppers on the stepper board, counted by the DAQ board
//   RIG_CHANNELS             1-4 load cells on the DAQ board (A0..A3)
//   RIG_MIN_INTERVAL_US      shortest step interval per axis (us), >= 500
//   RIG_MAX_INTERVAL_US      longest step interval per axis (us), <= 1000000
//   RIG_AXIS_TRAVEL_STEPS    {t0, ...}: each axis's travel, 0..t_i steps from zero (RIG_AXES values, 1-255)
//   RIG_AXIS_RELEASE_STEPS   {r0, ...}: optional (absent: every axis 0): how far each axis may pay out below
//                            zero (the rest), so its positions are -r_i..t_i (RIG_AXES values, r_i + t_i <= 255)
//   RIG_PROGRAMME_MAX        items of the stepper's programme table (1-255)
//   RIG_DAQ_RATE_MIN_HZ, RIG_DAQ_RATE_MAX_HZ, RIG_DAQ_RATE_DEFAULT_HZ   DAQ sample rates (Hz)
//   RIG_DAQ_BAUD, RIG_STEPPER_BAUD                                      serial line rates (8N1)
//   RIG_ADC_CLIP_LOW_COUNTS, RIG_ADC_CLIP_HIGH_COUNTS                   the load cells' clipping levels
//                                                                       (host-side analysis; not used on board)
//   RIG_STEPPER_TABLES_BYTES, RIG_STEPPER_TABLES_MAX_BYTES  the stepper's RAM budget as the host computed it
//                            (helpers/rigfile/capacity.py, the rule's one source): its programme table, stream
//                            state and shaper, and what the Uno's RAM leaves them; the stepper sketch asserts
//                            that its tables are exactly that size and fit
#ifndef FIRMWARE_COMMON_RIG_CONFIG_H
#define FIRMWARE_COMMON_RIG_CONFIG_H

#include <stdint.h>

#ifndef RIG_CONFIG_HEADER
#define RIG_CONFIG_HEADER "rig_config_paper.h"
#endif
#include RIG_CONFIG_HEADER

#if !defined(RIG_HASH) || !defined(RIG_NAME) || !defined(RIG_AXES) || !defined(RIG_CHANNELS)
#error "rig config: RIG_HASH, RIG_NAME, RIG_AXES and RIG_CHANNELS are required"
#endif
#if !defined(RIG_MIN_INTERVAL_US) || !defined(RIG_MAX_INTERVAL_US) || !defined(RIG_AXIS_TRAVEL_STEPS)
#error "rig config: RIG_MIN_INTERVAL_US, RIG_MAX_INTERVAL_US and RIG_AXIS_TRAVEL_STEPS are required"
#endif
#if !defined(RIG_PROGRAMME_MAX) || !defined(RIG_DAQ_RATE_MIN_HZ) || !defined(RIG_DAQ_RATE_MAX_HZ) || \
    !defined(RIG_DAQ_RATE_DEFAULT_HZ)
#error "rig config: RIG_PROGRAMME_MAX and RIG_DAQ_RATE_MIN_HZ/MAX_HZ/DEFAULT_HZ are required"
#endif
#if !defined(RIG_DAQ_BAUD) || !defined(RIG_STEPPER_BAUD) || !defined(RIG_ADC_CLIP_LOW_COUNTS) || \
    !defined(RIG_ADC_CLIP_HIGH_COUNTS)
#error "rig config: RIG_DAQ_BAUD, RIG_STEPPER_BAUD and RIG_ADC_CLIP_LOW/HIGH_COUNTS are required"
#endif
#if !defined(RIG_STEPPER_TABLES_BYTES) || !defined(RIG_STEPPER_TABLES_MAX_BYTES)
#error "rig config: RIG_STEPPER_TABLES_BYTES and RIG_STEPPER_TABLES_MAX_BYTES are required (generate the header: python -m helpers.rigfile.firmware_header)"
#endif
#if RIG_AXES < 1 || RIG_AXES > 4
#error "rig config: RIG_AXES must be 1-4 (the stepper board has four STEP/DIR pairs)"
#endif
#if RIG_CHANNELS < 1 || RIG_CHANNELS > 4
#error "rig config: RIG_CHANNELS must be 1-4 (the DAQ board samples A0..A3)"
#endif
#if RIG_MIN_INTERVAL_US < 500 || RIG_MAX_INTERVAL_US > 1000000L || RIG_MIN_INTERVAL_US > RIG_MAX_INTERVAL_US
#error "rig config: step intervals must satisfy 500 <= RIG_MIN_INTERVAL_US <= RIG_MAX_INTERVAL_US <= 1000000"
#endif
#if RIG_PROGRAMME_MAX < 1 || RIG_PROGRAMME_MAX > 255
#error "rig config: RIG_PROGRAMME_MAX must be 1-255"
#endif
#if RIG_DAQ_RATE_MIN_HZ < 31 || RIG_DAQ_RATE_MAX_HZ > 4000 || RIG_DAQ_RATE_MIN_HZ > RIG_DAQ_RATE_DEFAULT_HZ || \
    RIG_DAQ_RATE_DEFAULT_HZ > RIG_DAQ_RATE_MAX_HZ
#error "rig config: DAQ rates must satisfy 31 <= MIN <= DEFAULT <= MAX <= 4000 Hz (Timer1 /8 is 16-bit)"
#endif
#if RIG_ADC_CLIP_LOW_COUNTS < 0 || RIG_ADC_CLIP_HIGH_COUNTS > 1023 || RIG_ADC_CLIP_LOW_COUNTS >= RIG_ADC_CLIP_HIGH_COUNTS
#error "rig config: ADC clipping levels must satisfy 0 <= LOW < HIGH <= 1023"
#endif

#ifdef __cplusplus
// Each axis's travel (steps from zero), as a table; its length must be RIG_AXES.
static constexpr uint8_t rig_axis_travel[] = RIG_AXIS_TRAVEL_STEPS;
static_assert(sizeof(rig_axis_travel) == RIG_AXES, "rig config: RIG_AXIS_TRAVEL_STEPS needs RIG_AXES values");
// Each axis's paid-out range below zero (steps): its positions are -release..travel. Absent: none.
#ifdef RIG_AXIS_RELEASE_STEPS
#define RIG_HAS_RELEASE 1
static constexpr uint8_t rig_axis_release[] = RIG_AXIS_RELEASE_STEPS;
static_assert(sizeof(rig_axis_release) == RIG_AXES, "rig config: RIG_AXIS_RELEASE_STEPS needs RIG_AXES values");
#else
#define RIG_HAS_RELEASE 0
static constexpr uint8_t rig_axis_release[RIG_AXES] = {0};
#endif
// An item holds each axis's steps as an 8-bit count, at most release + travel.
static constexpr bool rig_spans_fit(uint8_t a) {
  return a >= RIG_AXES || ((uint16_t)rig_axis_travel[a] + rig_axis_release[a] <= 255 && rig_spans_fit(a + 1));
}
static_assert(rig_spans_fit(0), "rig config: RIG_AXIS_RELEASE_STEPS + RIG_AXIS_TRAVEL_STEPS must be <= 255 per axis");
static_assert(sizeof(RIG_HASH) == 9, "rig config: RIG_HASH must be 8 hex characters");
#endif

#endif
