// Stepper board: Arduino Uno driving up to four TB6600 drivers (RIG_AXES, from the rig config): axis 0 on
// STEP = D5, DIR = D6 (HIGH = pull); axes 1-3 on STEP = D2, D3, D4 and DIR = D10, D11, D12; one ENA = D7
// (HIGH disables every driver).
// Two modes, both with Timer1 step timing: a stored programme of segments and dwells (GO), and a stream of
// velocity set-points shaped on the board by one loaded input shaper (STREAM; V for axis 0, MV for every axis,
// each shaped by the one shaper with its own travel clamp). A programme item moves
// every axis by its own step count in one time window (MSEG; SEG is one on axis 0), the steps of each axis
// spread over the window Bresenham-style: step k of n at the first timer tick at or after k/n of the window.
// Protocol: firmware/PROTOCOL.md (RIG_STEPPER_BAUD, 115200 for the paper's rig, 8N1).
//
// Built by firmware/Makefile as C++ with `-include Arduino.h` (no IDE: functions are declared before use).
//
// Timing: Timer1 in CTC mode with a /8 prescaler (0.5 us ticks). Every event (a step, the end of a dwell) is
// scheduled relative to the previous one by reloading OCR1A inside the compare ISR, so step k of a segment
// falls exactly k * interval after the segment's start and the items run back to back, all in whole ticks
// from GO. Waits longer than 65536 ticks are split into chunks of at most 65536 ticks (each at least 32768).
// Each STEP edge is raised a fixed 8 us after its compare match (busy-wait on TCNT1), so the latency of other
// interrupts (UART) does not jitter it; Timer0's millis() interrupt is switched off for the same reason.
//
// Streaming: Timer1 runs free (normal mode, 0.5 us ticks from STREAM). Its compare B interrupt is the 100 Hz
// control tick: it takes the next set-point from a FIFO and plans the steps of the period after next
// (common/stream_plan.cpp), with interrupts re-enabled so that it never delays a step; compare A emits the
// planned steps from a queue, each STEP edge a fixed 16 us after its compare match (8 us in programme mode;
// several axes: a queue per axis, merged into a short lookahead of events, edges 24 us after their ticks).
// Test points (for a scope; the simavr tests log them): D8 (PB0) is HIGH while the control tick runs, D9 (PB1)
// while a streamed step is emitted.
//
// Safety: the compiled-in limits below are enforced whatever the host asks (in streaming mode on the shaped
// output: travel, speed); the driver is disabled at reset (ENA is driven HIGH in .init3, before the C runtime
// starts), on ABORT, on EN 0 and by the stream watchdog.

#include <avr/interrupt.h>
#include <avr/io.h>

#include "proto.h"
#include "reply.h"
#include "rig_config.h"
#include "stream_plan.h"

// The version reported in HELLO and PONG: the protocol version, then "+" and the rig config's hash.
#define FW_VERSION "2.3.0"
#define FW_ID FW_VERSION "+" RIG_HASH

// Compiled-in limits (PROTOCOL.md table), from the rig config (rig_config.h).
static const int32_t INTERVAL_MIN_US = RIG_MIN_INTERVAL_US;  // paper: 639 us, 400 mm/s at 0.25525 mm/step
static const int32_t INTERVAL_MAX_US = RIG_MAX_INTERVAL_US;  // paper: one step per second
static const int32_t DWELL_MAX_MS = 60000;
#define AXES RIG_AXES
#define PROGRAMME_MAX RIG_PROGRAMME_MAX

// The STEP edge is issued this many 0.5 us ticks after the compare match (longer than any other ISR).
// (16 us with several axes: the compare ISR of a multi-axis programme saves more registers before its edge,
// and a UART interrupt may come first.)
static const uint16_t STEP_LEAD_TICKS = AXES > 1 ? 32 : 16;
// Streaming: 16 us, since the control tick's short interrupt-free sections add to the UART's.
static const uint16_t STREAM_STEP_LEAD_TICKS = 32;

// Axis 0: STEP = D5 = PD5, DIR = D6 = PD6; ENA = D7 = PD7 (all drivers). Axes 1-3: STEP = D2, D3, D4 (PD2-PD4,
// so that the STEP edges of steps due at the same tick are one port write), DIR = D10, D11, D12 (PB2-PB4).
#define STEP_BIT _BV(PD5)
#define DIR_BIT _BV(PD6)
#define ENA_BIT _BV(PD7)
static const uint8_t AXIS_STEP_BIT[4] = {_BV(PD5), _BV(PD2), _BV(PD3), _BV(PD4)};
static const uint8_t AXIS_DIR_BIT[4] = {_BV(PD6), _BV(PB2), _BV(PB3), _BV(PB4)};  // axis 0 on PORTD, others PORTB
static uint8_t all_step_bits() {
  uint8_t m = 0;
  for (uint8_t a = 0; a < AXES; a++) m |= AXIS_STEP_BIT[a];
  return m;
}
static uint8_t dir_bits_b() {
  uint8_t m = 0;
  for (uint8_t a = 1; a < AXES; a++) m |= AXIS_DIR_BIT[a];
  return m;
}
#define TP_TICK_BIT _BV(PB0)  // test point D8: control tick running
#define TP_STEP_BIT _BV(PB1)  // test point D9: streamed step being emitted

// Stack painting: the RAM between the static data and the stack is filled with a pattern before the C runtime
// starts; MEM reports how much of it was never overwritten, i.e. the least free stack there has ever been.
#define STACK_PAINT 0xC5
extern uint8_t __heap_start;
void paint_stack_at_reset(void) __attribute__((naked, used, section(".init3")));
void paint_stack_at_reset(void) {
  for (uint8_t *p = &__heap_start; p < (uint8_t *)RAMEND; p++) *p = STACK_PAINT;
}

static uint16_t free_stack_min() {
  uint16_t n = 0;
  for (const uint8_t *p = &__heap_start; p < (const uint8_t *)RAMEND && *p == STACK_PAINT; p++) n++;
  return n;
}

// Disable the driver as early as possible after reset (before .data/.bss initialisation and main()).
void ena_disable_at_reset(void) __attribute__((naked, used, section(".init3")));
void ena_disable_at_reset(void) {
  PORTD |= ENA_BIT;
  DDRD |= ENA_BIT;
}

// ---------------------------------------------------------------------------------------------------------
// Programme

enum ItemKind : uint8_t { ITEM_SEG = 1, ITEM_WAIT = 2 };

// SEG (axis 0) and MSEG are both a window of `ticks` in which axis a makes n[a] steps (step k of n at
// ceil(k * ticks / n) from the window's start: for SEG, k * interval exactly); WAIT is a window without steps.
struct Item {
  uint32_t ticks;      // the window (SEG: n * interval; WAIT: the dwell), in 0.5 us ticks
  uint8_t n[AXES];     // steps of each axis (<= its release + travel)
  uint8_t release;     // bit a set: axis a releases (-1), else pulls (+1)
  uint8_t kind;
};

// Streaming state (PROTOCOL.md "Streaming"): the planner with every axis's position and set-point history, the
// queue of planned steps of each axis and the set-point FIFO (the shaper, sp_shaper, is kept apart: it stays
// loaded). One axis: about 350 bytes beside the programme table (the boards' constant strings are kept in
// flash). Several axes: the stream's state shares its RAM with the programme table (STREAM empties the
// programme; the programme cannot be edited while streaming).
// Planned steps not yet emitted, per axis: two periods ahead, a power of two. A 10 ms period holds at most
// 10000 / RIG_MIN_INTERVAL_US + 1 steps: 16 on the paper's rig (639 us), 20 on a finer one (524 us).
#if 10000L / RIG_MIN_INTERVAL_US + 1 <= 16
#define STEP_QUEUE 32
#else
#define STEP_QUEUE 64
#endif
#define SETPOINT_FIFO 8
struct StreamMem {
  Planner planner;
  uint16_t step_time[AXES][STEP_QUEUE];   // Timer1 value (ticks from STREAM, mod 2^16) of each queued step
  uint8_t step_up[AXES][STEP_QUEUE / 8];  // bit set: the step is a pull (+1)
  int16_t fifo[SETPOINT_FIFO][AXES];      // set-points received and not yet taken by a control tick
};
#if AXES > 1
static union {
  Item prog[PROGRAMME_MAX];
  StreamMem st;
} mem;
#define prog mem.prog
#define st mem.st
static const uint16_t TABLES_BYTES = sizeof(mem) + sizeof(SpShaper);
#else
static Item prog[PROGRAMME_MAX];
static StreamMem st;
static const uint16_t TABLES_BYTES = sizeof(prog) + sizeof(StreamMem) + sizeof(SpShaper);
#endif
static uint8_t prog_len;

// RAM budget, checked at compile time with the host's numbers: helpers/rigfile/capacity.py is the rule's one
// source (rig check and the header generator refuse a rig whose tables do not fit) and the generated header
// carries what it computed: the size of these tables (the programme table, the stream's state and the shaper)
// and what the Uno's RAM leaves them beside the rest of the static data (serial and line buffers, run state:
// 460-575 bytes by the number of axes) and 320 bytes of stack (the deepest stack measured in simavr: 239 bytes).
// The first assertion keeps the host's model of these tables honest; the second is the rule.
static const uint16_t RAM_BYTES = RAMEND + 1 - RAMSTART;
static_assert(TABLES_BYTES == RIG_STEPPER_TABLES_BYTES,
              "rig config: the stepper's tables are not the size helpers/rigfile/capacity.py computes "
              "(RIG_STEPPER_TABLES_BYTES): update its model, then regenerate the header");
static_assert(TABLES_BYTES <= RIG_STEPPER_TABLES_MAX_BYTES && RIG_STEPPER_TABLES_MAX_BYTES < RAM_BYTES,
              "rig config: the programme table (RIG_PROGRAMME_MAX x RIG_AXES) does not fit the Uno's RAM");

// Run state (ISR-owned while running).
static volatile uint8_t running;
static volatile uint8_t done_flag;    // one byte: set by the ISR, cleared by the main loop
static volatile int16_t position[AXES];  // steps from zero, + for pulls
static uint8_t cur;                   // index of the item in progress
static uint32_t rem_ticks;            // ticks still to wait after the present chunk
// The item in progress: the time of the present event and, per axis, its next step by the Bresenham
// recurrence k * window = n * f + e (0 <= e < n): step k at f + (e != 0) ticks from the item's start.
struct AxisRun {
  uint32_t f, q;   // f: floor(k * window / n) of the next step k; q = window / n
  uint8_t e, r;    // e: the remainder of the next step; r = window % n
  uint8_t left;    // steps still to issue
};
static AxisRun ax[AXES];
static volatile uint8_t enabled;      // driver enabled (ENA LOW); the stream watchdog may clear it

static void timer_stop() {
  TCCR1B = 0;
  TIMSK1 = 0;
}

// Time bookkeeping of a programme: TCNT1 counts from the last compare match (CTC), whose time is `base_t`
// (ticks from the start of the item in progress; <= 0 just after an item began between two matches), and
// `period` is the length of the wait loaded last, so that each match advances `base_t` by it.
static int32_t base_t;
static uint32_t period;

// Loads the wait until the next event, `ticks` after the last compare match (called just after a match, while
// TCNT1 is still well below `ticks`, or with the timer stopped): OCR1A = ticks - 1; a wait over 65536 ticks
// starts with a chunk of 32768 and the ISR loads the rest.
static void schedule(uint32_t ticks) {
  if (ticks > 65536UL) {
    OCR1A = 32768 - 1;
    rem_ticks = ticks - 32768;
    period = 32768;
  } else {
    OCR1A = (uint16_t)(ticks - 1);
    rem_ticks = 0;
    period = ticks;
  }
}

static void set_axis_dir(uint8_t a, bool pull) {
  if (a == 0) {
    if (pull) PORTD |= DIR_BIT;
    else PORTD &= ~DIR_BIT;
  } else {
    if (pull) PORTB |= AXIS_DIR_BIT[a];
    else PORTB &= (uint8_t)~AXIS_DIR_BIT[a];
  }
}

static inline uint32_t axis_next(const AxisRun &r) { return r.f + (r.e ? 1 : 0); }

// The item's next events, planned ahead into a small queue, so that the compare ISR raises an event's STEP
// edges without computing first, and events due a few ticks after one another (steps of different axes) are
// each raised at their own tick: (evq_gap, evq_mask), the gap in ticks after the previous event (the first:
// after the item's start), oldest first. Each axis's Bresenham state is advanced past every queued event;
// `more_steps` is clear once every step is queued.
#define EVQ 4  // a power of two; at most one event per axis falls within the shortest step interval
static uint32_t evq_gap[EVQ];
static uint8_t evq_close[EVQ];  // the gap when it is under CLOSE_TICKS (to be chained without 32-bit work), else 0
#define CLOSE_TICKS 200
static uint32_t evq_last;  // the time of the last queued event (ticks from the item's start)
static uint8_t evq_mask[EVQ];
static uint8_t evq_head, evq_n;
static uint8_t more_steps;

// Queues the earliest next step among the axes with steps left, and advances those axes past it.
static void produce() {
  uint32_t t = 0xFFFFFFFFUL;
  uint8_t mask = 0;
  for (uint8_t a = 0; a < AXES; a++) {
    if (!ax[a].left) continue;
    uint32_t ta = axis_next(ax[a]);
    if (ta < t) {
      t = ta;
      mask = AXIS_STEP_BIT[a];
    } else if (ta == t) {
      mask |= AXIS_STEP_BIT[a];
    }
  }
  if (!mask) {
    more_steps = 0;
    return;
  }
  uint8_t i = (uint8_t)((evq_head + evq_n) & (EVQ - 1));
  evq_gap[i] = t - evq_last;
  evq_close[i] = (t - evq_last < CLOSE_TICKS) ? (uint8_t)(t - evq_last) : 0;
  evq_last = t;
  evq_mask[i] = mask;
  evq_n++;
  const Item &it = prog[cur];
  for (uint8_t a = 0; a < AXES; a++) {
    AxisRun &r = ax[a];
    if (!(mask & AXIS_STEP_BIT[a])) continue;
    if (--r.left) {  // step k + 1: (k + 1) * window = n * (f + q) + (e + r), carried
      r.f += r.q;
      uint16_t e = (uint16_t)r.e + r.r;
      if (e >= it.n[a]) {
        e -= it.n[a];
        r.f++;
      }
      r.e = (uint8_t)e;
    }
  }
}

// The positions after the STEP edges of `mask` (called as they go up).
static void count_steps(uint8_t mask) {
  const Item &it = prog[cur];
  for (uint8_t a = 0; a < AXES; a++) {
    if (mask & AXIS_STEP_BIT[a]) position[a] += (it.release & (1 << a)) ? -1 : 1;
  }
}

// Starts item `cur` at the present event time (skipping zero-length dwells); finishes after the last one.
static void start_item() {
  while (cur < prog_len) {
    Item &it = prog[cur];
    if (it.kind == ITEM_SEG) {
      for (uint8_t a = 0; a < AXES; a++) {
        AxisRun &r = ax[a];
        r.left = it.n[a];
        if (!r.left) continue;
        set_axis_dir(a, !(it.release & (1 << a)));
        r.q = it.ticks / r.left;  // step 1 of n: 1 * window = n * q + r
        r.r = (uint8_t)(it.ticks % r.left);
        r.f = r.q;
        r.e = r.r;
      }
      evq_head = evq_n = 0;
      evq_last = 0;
      more_steps = 1;
      for (uint8_t k = 0; k < EVQ; k++) produce();  // its first events (the first >= 639 us away); the
                                                     // compare ISRs plan the rest ahead
      schedule((uint32_t)((int32_t)evq_gap[evq_head] - base_t));
      return;
    }
    if (it.ticks > 0) {
      for (uint8_t a = 0; a < AXES; a++) ax[a].left = 0;
      schedule((uint32_t)((int32_t)it.ticks - base_t));
      return;
    }
    cur++;
  }
  timer_stop();
  running = 0;
  done_flag = 1;
}

static void stream_step_isr();
static volatile uint8_t stream_timer;  // Timer1 runs the stream (normal mode) rather than a programme (CTC)

// Serves the queued events after the one whose STEP edges (`high`, up at tick `rise` from the last match)
// have just been raised: every event due too soon for another interrupt (a step of another axis a few ticks
// later) is raised here at its own tick + STEP_LEAD_TICKS by busy-waiting; then the queue is refilled while
// the next event is far enough, the pulses end (each lasts at least PULSE_TICKS) and the next event is
// scheduled. Returns false when the item's last step has been issued.
static const uint16_t PULSE_TICKS = 10;    // 5 us high (the TB6600 needs >= 2.5 us)
static const uint16_t CHAIN_TICKS = 24;    // an edge closer than this to TCNT1 is raised in this interrupt
static const uint16_t REFILL_TICKS = 200;  // planning one event takes under 100 us (4 axes)

// Waits for the end of the pulses up (at least PULSE_TICKS since `rise`) and lowers them.
static inline void end_pulses(uint8_t high, uint16_t rise) {
  while ((uint16_t)(TCNT1 - rise) < PULSE_TICKS) {
  }
  PORTD &= (uint8_t)~high;
}

static inline __attribute__((always_inline)) bool serve_steps(uint8_t high, uint16_t rise) {
  uint8_t raised = high;
  uint16_t at = (uint16_t)(rise - STEP_LEAD_TICKS);  // the tick (from the last match) of the last event raised
  for (;;) {
    while (evq_n) {  // raise every queued event that is due too soon for another interrupt
      uint8_t h = evq_head;
      uint8_t g = evq_close[h];
      uint16_t t;
      if (g) {  // the fast path for a step a few ticks after the last one
        t = (uint16_t)(at + g);
        if ((int16_t)(t - TCNT1) >= (int16_t)CHAIN_TICKS) break;
      } else {  // a longer gap that planning has brought near (never expected: planning stops well before)
        uint32_t d = at + evq_gap[h];
        if (d >= (uint32_t)TCNT1 + CHAIN_TICKS) break;
        t = (uint16_t)d;
      }
      uint8_t m = evq_mask[h];
      uint16_t edge = (uint16_t)(t + STEP_LEAD_TICKS);
      while (TCNT1 < edge) {
      }
      PORTD |= m;
      evq_head = (uint8_t)((h + 1) & (EVQ - 1));
      evq_n--;
      raised |= m;
      high |= m;
      rise = edge;
      at = t;
    }
    if (raised) {
      count_steps(raised);
      raised = 0;
    }
    uint32_t delta = evq_n ? at + evq_gap[evq_head] : 0;  // the next event, in ticks from the last match
    if (high && (!evq_n || delta >= (uint32_t)TCNT1 + CHAIN_TICKS + PULSE_TICKS)) {
      end_pulses(high, rise);
      high = 0;
    }
    // plan ahead while the next event is far enough (or unknown)
    while (more_steps && evq_n < EVQ && (!evq_n || delta >= (uint32_t)TCNT1 + REFILL_TICKS)) {
      produce();
      if (evq_n == 1) delta = at + evq_gap[evq_head];
    }
    if (!evq_n) {  // every step issued: the item is over (its last step is at the end of its window)
      if (high) end_pulses(high, rise);
      return false;
    }
    if (delta < (uint32_t)TCNT1 + CHAIN_TICKS || high) continue;  // close, or pulses still up
    schedule(delta);
    return true;
  }
}

ISR(TIMER1_COMPA_vect) {
  if (stream_timer) {
    stream_step_isr();
    return;
  }
  if (rem_ticks) {
    uint32_t r = rem_ticks;
    base_t += (int32_t)period;
    if (r > 65536UL) {
      OCR1A = 32767;
      rem_ticks = r - 32768;
      period = 32768;
    } else {
      OCR1A = (uint16_t)(r - 1);
      rem_ticks = 0;
      period = r;
    }
    return;
  }
  Item &it = prog[cur];
  if (it.kind == ITEM_SEG) {
    // The axes whose next step is due now step together: one port write, a fixed STEP_LEAD_TICKS after the
    // compare match whatever the interrupt latency (another ISR may delay this one by a few us): every step
    // is late by the same 8 us.
    uint8_t mask = evq_mask[evq_head];
    while (TCNT1 < STEP_LEAD_TICKS) {
    }
    PORTD |= mask;
    OCR1A = 0xFFFF;  // no compare match until the next event is scheduled (TCNT1 counts from this match)
    uint8_t h = (uint8_t)((evq_head + 1) & (EVQ - 1));
    evq_head = h;
    evq_n--;
    uint16_t rise = STEP_LEAD_TICKS;
    uint8_t g = evq_n ? evq_close[h] : 0;
    if (g && g < CHAIN_TICKS) {  // a step of another axis a few ticks later: raise it first
      uint8_t m = evq_mask[h];
      rise = (uint16_t)(STEP_LEAD_TICKS + g);
      while (TCNT1 < rise) {
      }
      PORTD |= m;
      mask |= m;
      evq_head = (uint8_t)((h + 1) & (EVQ - 1));
      evq_n--;
    }
    base_t += (int32_t)period;
    if (serve_steps(mask, rise)) return;
  } else {
    base_t += (int32_t)period;
  }
  base_t -= (int32_t)it.ticks;  // from the next item's start (this item's end)
  cur++;
  // Planning the next item (a division and EVQ events per axis: up to about 400 us for four axes) runs with
  // interrupts enabled, so that the UART's receiver is served meanwhile; no compare match can come before
  // start_item() loads the next one (the next item's first event is >= 639 us away).
  OCR1A = 0xFFFF;
  sei();
  start_item();
  cli();
}

// ---------------------------------------------------------------------------------------------------------
// Streaming (PROTOCOL.md "Streaming"): a FIFO of set-points, the control tick (Timer1 compare B, 100 Hz) that
// plans one period at a time, and the step queue that compare A empties.

enum StreamState : uint8_t { ST_IDLE = 0, ST_ACTIVE, ST_ENDING, ST_WATCHDOG };
static const uint8_t WATCHDOG_PERIODS = 10;  // 100 ms without a set-point

static volatile uint8_t stream_state;
static volatile uint8_t sq_head[AXES], sq_count[AXES];  // each axis's step queue: the control tick adds, compare A takes
static volatile uint8_t fifo_head, fifo_count;    // the set-point FIFO: V adds, the control tick takes
static volatile uint32_t next_period;             // the period the next control tick plans
static volatile uint32_t end_period;              // the first period fed with zero (END or the watchdog)
static volatile uint8_t queue_overflow;           // never expected (at most 32 steps are ever pending)
static volatile uint8_t tick_busy;
static uint8_t underruns;                         // control ticks in a row without a set-point
static uint32_t last_nonzero;                     // the last period with a non-zero set-point
static uint8_t finishing;                         // no step can follow: the stream stops at tick finish_at
static uint32_t finish_at;

// shaper loading (SHAPER, then IMP 0 .. IMP n-1)
static uint8_t shaper_ready;   // a complete, valid shaper is in sp_shaper
static uint8_t shaper_expect;  // impulses announced by SHAPER; 0 when not loading
static uint8_t shaper_next;    // the index the next IMP must have
static uint8_t shaper_neg;     // negative amplitudes allowed
static int32_t shaper_sum;

// notices, queued by the control tick and sent by the main loop
enum NoticeKind : uint8_t { NOTICE_SPEED = SP_NOTICE_SPEED, NOTICE_TRAVEL = SP_NOTICE_TRAVEL, NOTICE_WATCHDOG };
#define NOTICES 4
static uint8_t notice_kind[NOTICES];  // the kind; several axes: the axis in the high nibble
static int32_t notice_value[NOTICES];
static volatile uint8_t notice_head, notice_count;

static void push_notice(uint8_t kind, int32_t value) {
  uint8_t sreg = SREG;
  cli();
  if (notice_count < NOTICES) {
    uint8_t i = (uint8_t)((notice_head + notice_count) & (NOTICES - 1));
    notice_kind[i] = kind;
    notice_value[i] = value;
    notice_count++;
  }
  SREG = sreg;
}

void sp_notice(uint8_t kind, uint8_t axis, int32_t value) { push_notice((uint8_t)(kind | (axis << 4)), value); }

static inline uint8_t step_is_up(uint8_t a, uint8_t i) { return st.step_up[a][i >> 3] & (uint8_t)(1 << (i & 7)); }

#if AXES == 1
static inline void set_dir_for(uint8_t i) {
  if (step_is_up(0, i)) PORTD |= DIR_BIT;
  else PORTD &= ~DIR_BIT;
}

// Queues one planned step (called by the planner from the control tick, interrupts enabled).
void sp_emit_step(uint8_t, uint32_t tick, int8_t dir) {
  uint8_t sreg = SREG;
  cli();
  if (sq_count[0] >= STEP_QUEUE) {
    queue_overflow = 1;
    SREG = sreg;
    return;
  }
  uint8_t i = (uint8_t)((sq_head[0] + sq_count[0]) & (STEP_QUEUE - 1));
  st.step_time[0][i] = (uint16_t)tick;
  if (dir > 0) st.step_up[0][i >> 3] |= (uint8_t)(1 << (i & 7));
  else st.step_up[0][i >> 3] &= (uint8_t)~(1 << (i & 7));
  if (sq_count[0]++ == 0) {  // the step generator was idle: arm it (DIR set at least 8 ms before this step)
    set_dir_for(i);
    OCR1A = (uint16_t)tick;
    TIFR1 = _BV(OCF1A);
    TIMSK1 |= _BV(OCIE1A);
  }
  SREG = sreg;
}

// Compare A in streaming mode: the step at the head of the queue, its edge 16 us after the compare match.
static void stream_step_isr() {
  PORTB |= TP_STEP_BIT;
  uint8_t i = sq_head[0];
  uint16_t edge = OCR1A + STREAM_STEP_LEAD_TICKS;
  while ((int16_t)(TCNT1 - edge) < 0) {
  }
  PORTD |= STEP_BIT;
  position[0] += step_is_up(0, i) ? 1 : -1;
  __builtin_avr_delay_cycles(64);  // TB6600 needs >= 2.5 us high
  PORTD &= ~STEP_BIT;
  i = (uint8_t)((i + 1) & (STEP_QUEUE - 1));
  sq_head[0] = i;
  if (--sq_count[0]) {
    set_dir_for(i);  // at least 600 us before its step (steps are 639 us apart or more)
    OCR1A = st.step_time[0][i];
  } else {
    TIMSK1 &= ~_BV(OCIE1A);
  }
  PORTB &= ~TP_STEP_BIT;
}
#else
// Several axes: each axis's planned steps queue apart (each in time order). Compare A serves a short lookahead of
// events (a time and the axes stepping then), merged from the axes' queues outside the step edges' timing:
// the earliest queued steps become the next event, but only steps before `sq_horizon` (every step before it is
// planned: the control tick plans one axis after another, and a later axis may plan an earlier step).
#define SEVQ 4  // a power of two
static uint16_t sev_t[SEVQ];   // the event's tick (ticks from STREAM, mod 2^16)
static uint8_t sev_axes[SEVQ]; // bit a: axis a steps
static uint8_t sev_bits[SEVQ]; // their STEP bits (PORTD)
static uint8_t sev_up[SEVQ];   // bit a: axis a's step is a pull
static uint8_t sev_head, sev_n;
static uint16_t sev_last;      // the time of the last event merged (every queued step is at or after it)
static uint16_t sq_horizon;    // every step before this tick is planned (at most 2 periods after sev_last)
static uint8_t sev_pend[AXES]; // events in the lookahead with a step of axis a

// Queues one planned step (called by the planner from the control tick, interrupts enabled).
void sp_emit_step(uint8_t a, uint32_t tick, int8_t dir) {
  uint8_t sreg = SREG;
  cli();
  if (sq_count[a] >= STEP_QUEUE) {
    queue_overflow = 1;
    SREG = sreg;
    return;
  }
  uint8_t i = (uint8_t)((sq_head[a] + sq_count[a]) & (STEP_QUEUE - 1));
  st.step_time[a][i] = (uint16_t)tick;
  if (dir > 0) st.step_up[a][i >> 3] |= (uint8_t)(1 << (i & 7));
  else st.step_up[a][i >> 3] &= (uint8_t)~(1 << (i & 7));
  sq_count[a]++;
  SREG = sreg;
}

// Merges the earliest queued steps (before the horizon) into the next event of the lookahead; false if none.
// Sets an axis's DIR when it has no earlier step in the lookahead (its last pulse is over: called with no
// pulse up). Interrupts off.
static bool sev_produce() {
  uint16_t best = 0xFFFF;
  uint16_t limit = (uint16_t)(sq_horizon - sev_last);
  uint8_t axes = 0;
  for (uint8_t a = 0; a < AXES; a++) {
    if (!sq_count[a]) continue;
    uint16_t d = (uint16_t)(st.step_time[a][sq_head[a]] - sev_last);
    if (d >= limit) continue;
    if (d < best) {
      best = d;
      axes = (uint8_t)(1 << a);
    } else if (d == best) {
      axes |= (uint8_t)(1 << a);
    }
  }
  if (!axes) return false;
  uint8_t e = (uint8_t)((sev_head + sev_n) & (SEVQ - 1));
  uint8_t bits = 0, up = 0;
  for (uint8_t a = 0; a < AXES; a++) {
    if (!(axes & (1 << a))) continue;
    uint8_t i = sq_head[a];
    bool pull = step_is_up(a, i);
    if (pull) up |= (uint8_t)(1 << a);
    bits |= AXIS_STEP_BIT[a];
    if (!sev_pend[a]) set_axis_dir(a, pull);
    sev_pend[a]++;
    sq_head[a] = (uint8_t)((i + 1) & (STEP_QUEUE - 1));
    sq_count[a]--;
  }
  sev_last = (uint16_t)(sev_last + best);
  sev_t[e] = sev_last;
  sev_axes[e] = axes;
  sev_bits[e] = bits;
  sev_up[e] = up;
  sev_n++;
  return true;
}

// Compare A of a multi-axis stream: the STEP edges follow their ticks by STREAM_LEAD_AXES; events due too soon
// for another interrupt are raised in this one (each at its own tick + the lead), then the pulses end, each
// stepped axis's DIR is set for its next event, the lookahead is refilled while the next event is far enough,
// and compare A is set for it.
static const uint16_t STREAM_LEAD_AXES = 48;    // 24 us
static const uint16_t STREAM_CHAIN_TICKS = 24;  // an event closer than this to TCNT1 is raised in this interrupt
static const uint16_t STREAM_REFILL_TICKS = 100;  // merging one event takes under 40 us (four axes)
static const uint16_t FOLLOW_TICKS = 16;  // an event this close after another is raised straight after it

// True when tick `t` (at or after `ref`, a tick just past) is less than `margin` ticks after TCNT1. (Events are
// up to two periods ahead, more than 2^15 ticks: they are compared as distances from `ref`, never signed.)
static inline bool due_within(uint16_t t, uint16_t ref, uint16_t margin) {
  return (uint16_t)(t - ref) < (uint16_t)((uint16_t)(TCNT1 - ref) + margin);
}

// Busy-waits for tick `edge` (at most 127 ticks ahead): on the low byte of TCNT1, a 5-cycle loop, so that the
// port write follows the tick by 0-5 cycles plus a constant.
static inline void wait_edge(uint16_t edge) {
  if ((int16_t)(TCNT1 - edge) >= 0) return;  // (already there)
  uint8_t e = (uint8_t)edge;
  while ((int8_t)(TCNT1L - e) < 0) {
  }
}

// (Not inlined into the compare vector: its programme path keeps its register allocation and timing.)
static void __attribute__((noinline)) stream_step_isr() {
  PORTB |= TP_STEP_BIT;
  uint8_t high = 0, stepped = 0;
  uint16_t rise = 0, ref = 0;
  for (;;) {
    // raise the due event and every one due too soon after it (their times and bits are ready)
    uint8_t h = sev_head, first = h, n = 0;
    do {
      uint16_t tt = sev_t[h];
      uint16_t edge = (uint16_t)(tt + STREAM_LEAD_AXES);
      uint8_t bits = sev_bits[h];
      uint8_t h2 = (uint8_t)((h + 1) & (SEVQ - 1));
      // an event up to FOLLOW_TICKS later: its edges straight after these, at its own edge (no loop between)
      uint16_t gap = (uint16_t)(sev_t[h2] - tt);
      uint8_t bits2 = (n + 1 < sev_n && gap <= FOLLOW_TICKS) ? sev_bits[h2] : 0;
      uint16_t edge2 = (uint16_t)(edge + gap);
      uint8_t one = gap == 1;
      wait_edge(edge);
      PORTD |= bits;
      if (bits2) {
        if (!one) wait_edge(edge2);
        PORTD |= bits2;  // (one tick later: about 8 cycles after the first write)
        bits |= bits2;
        edge = edge2;
        h = h2;
        n++;
      }
      rise = edge;
      ref = (uint16_t)(edge - STREAM_LEAD_AXES);
      high |= bits;
      h = (uint8_t)((h + 1) & (SEVQ - 1));
      n++;
    } while (n < sev_n && due_within(sev_t[h], ref, STREAM_CHAIN_TICKS));
    sev_head = h;
    sev_n = (uint8_t)(sev_n - n);
    for (uint8_t j = 0; j < n; j++) {  // the positions after these steps
      uint8_t e = (uint8_t)((first + j) & (SEVQ - 1));
      uint8_t axes = sev_axes[e], up = sev_up[e];
      stepped |= axes;
      for (uint8_t a = 0; a < AXES; a++) {
        if (!(axes & (1 << a))) continue;
        position[a] += (up & (1 << a)) ? 1 : -1;
        sev_pend[a]--;
      }
    }
    if (sev_n && due_within(sev_t[h], ref, STREAM_CHAIN_TICKS + PULSE_TICKS)) continue;
    end_pulses(high, rise);
    high = 0;
    for (uint8_t a = 0; a < AXES; a++) {  // DIR of each stepped axis's next step in the lookahead
      if (!(stepped & (1 << a)) || !sev_pend[a]) continue;
      for (uint8_t j = 0; j < sev_n; j++) {
        uint8_t e = (uint8_t)((sev_head + j) & (SEVQ - 1));
        if (sev_axes[e] & (1 << a)) {
          set_axis_dir(a, sev_up[e] & (1 << a));
          break;
        }
      }
    }
    stepped = 0;
    while (sev_n < SEVQ && (!sev_n || !due_within(sev_t[sev_head], ref, STREAM_REFILL_TICKS))) {
      if (!sev_produce()) break;
    }
    if (!sev_n) {
      TIMSK1 &= ~_BV(OCIE1A);
      break;
    }
    if (due_within(sev_t[sev_head], ref, STREAM_CHAIN_TICKS)) continue;
    OCR1A = sev_t[sev_head];
    break;
  }
  PORTB &= ~TP_STEP_BIT;
}

// After the control tick has planned period k: every step before (k + 2) T is planned; an idle step generator
// starts on the new steps.
static void stream_planned(uint32_t k) {
  cli();
  if (!sev_n) sev_last = (uint16_t)(k * SP_PERIOD_TICKS);  // (no step is queued before (k + 1) T)
  sq_horizon = (uint16_t)((k + 2) * SP_PERIOD_TICKS);
  if (!(TIMSK1 & _BV(OCIE1A))) {
    while (sev_n < SEVQ && sev_produce()) {
    }
    if (sev_n) {
      OCR1A = sev_t[sev_head];
      TIFR1 = _BV(OCF1A);
      TIMSK1 |= _BV(OCIE1A);
    }
  }
  sei();
}
#endif

static void stream_stop_timer() {
  timer_stop();
  stream_timer = 0;
  stream_state = ST_IDLE;
  finishing = 0;
  for (uint8_t a = 0; a < AXES; a++) sq_count[a] = 0;
  fifo_count = 0;
}

// The control tick: takes the set-points of the next period and plans it. Runs with interrupts enabled, so the
// step interrupt (and the UART) preempt it; it is the only writer of the planner.
ISR(TIMER1_COMPB_vect, ISR_NOBLOCK) {
  if (tick_busy) return;  // cannot happen (a tick takes about 1 ms of its 10 ms), but never re-enter
  tick_busy = 1;
  PORTB |= TP_TICK_BIT;
  cli();
  OCR1B += SP_PERIOD_TICKS;  // 16-bit timer registers share one TEMP byte with compare A: interrupts off
  sei();
  // The main loop cannot run during this interrupt and compare A does not touch the FIFO or the counters
  // below, so they need no further protection (the main loop changes them with interrupts off).
  uint32_t k = next_period;
  int16_t v[AXES];
  for (uint8_t a = 0; a < AXES; a++) v[a] = 0;
  uint8_t state = stream_state;
  if (fifo_count) {
    for (uint8_t a = 0; a < AXES; a++) v[a] = st.fifo[fifo_head][a];
    fifo_head = (uint8_t)((fifo_head + 1) & (SETPOINT_FIFO - 1));
    fifo_count--;
    underruns = 0;
  } else if (state == ST_ACTIVE) {
    if (++underruns > WATCHDOG_PERIODS) {  // the stream stopped: feed zero from now on
      stream_state = state = ST_WATCHDOG;
      end_period = k;
      push_notice(NOTICE_WATCHDOG, (int32_t)k);
    }
    // else an underrun: the period moves nothing (2.1.0; 2.0.0 held the last set-point, moving the cable
    // further than commanded whenever the host was late)
  }
  next_period = k + 1;
  if (finishing && k >= finish_at) {  // every planned step has been emitted
    cli();
    uint8_t watchdog = stream_state == ST_WATCHDOG;
    stream_stop_timer();
    if (watchdog) {
      PORTD |= ENA_BIT;
      enabled = 0;
    }
    done_flag = 1;
    sei();
  } else {
    st.planner.plan_period(k, v);
#if AXES > 1
    stream_planned(k);
#endif
    for (uint8_t a = 0; a < AXES; a++) {
      if (v[a]) last_nonzero = k;
    }
    if (!finishing && state != ST_ACTIVE && k >= end_period &&
        k - last_nonzero >= (uint32_t)sp_shaper.q_max + 2) {
      finishing = 1;  // every impulse now sees zero: the last step is planned
      finish_at = k + 3;
    }
  }
  PORTB &= ~TP_TICK_BIT;
  tick_busy = 0;
}

static int16_t read_position(uint8_t a);

static void stream_start() {
  int16_t p[AXES];
  for (uint8_t a = 0; a < AXES; a++) p[a] = read_position(a);
  st.planner.start(p);  // the timer is stopped: nothing else touches the planner
  cli();
  timer_stop();
  for (uint8_t a = 0; a < AXES; a++) sq_head[a] = sq_count[a] = 0;
#if AXES > 1
  sev_head = sev_n = 0;
  sev_last = 0;
  sq_horizon = SP_PERIOD_TICKS;  // (nothing is planned before 2 T)
  for (uint8_t a = 0; a < AXES; a++) sev_pend[a] = 0;
#endif
  fifo_head = fifo_count = 0;
  next_period = 1;
  end_period = 0xFFFFFFFFUL;
  underruns = 0;
  last_nonzero = 0;
  finishing = 0;
  queue_overflow = 0;
  tick_busy = 0;
  notice_count = 0;
  done_flag = 0;
  stream_state = ST_ACTIVE;
  stream_timer = 1;
  TCCR1A = 0;
  TCNT1 = 0;
  OCR1B = SP_PERIOD_TICKS;
  TIFR1 = _BV(OCF1A) | _BV(OCF1B) | _BV(TOV1);
  TIMSK1 = _BV(OCIE1B);
  TCCR1B = _BV(CS11);  // normal mode, clk/8: 0.5 us ticks from now (STREAM)
  sei();
}

static void run_abort() {
  cli();
  timer_stop();
  running = 0;
  done_flag = 0;
  stream_stop_timer();
  sei();
  PORTD |= ENA_BIT;
  enabled = 0;
}

static int16_t read_position(uint8_t a) {
  cli();
  int16_t p = position[a];
  sei();
  return p;
}
static int16_t read_position() { return read_position(0); }

static void run_go() {
  cli();
  cur = 0;
  base_t = 0;
  running = 1;
  done_flag = 0;
  TCCR1A = 0;
  TCCR1B = 0;
  TCNT1 = 0;
  OCR1A = 0xFFFF;
  TIFR1 = _BV(OCF1A);
  TCCR1B = _BV(WGM12) | _BV(CS11);  // t0 = now: CTC on OCR1A, clk/8, 0.5 us ticks
  // Plans the first events and sets OCR1A for the first (>= 639 us away; planning four axes takes under
  // 400 us), so the planning does not delay the programme's time 0 after GO.
  start_item();
  if (running) TIMSK1 = _BV(OCIE1A);
  sei();
}

// ---------------------------------------------------------------------------------------------------------
// Output

static void serial_write(const uint8_t *buf, uint8_t n) { Serial.write(buf, n); }

static Reply out = {{}, serial_write};

// ---------------------------------------------------------------------------------------------------------
// Commands

// "ERR RANGE <text><lo><sep><hi><suffix>": range texts built from the rig config's limits (the paper's
// build sends exactly the texts of firmware 2.1.0, e.g. "ERR RANGE n_steps 1-156").
static void err_range(const char *text, int32_t lo, const char *sep, int32_t hi, const char *suffix) {
  out.begin();
  out.line.str_P(PSTR("ERR RANGE "));
  out.line.str_P(text);
  out.line.i32(lo);
  out.line.str_P(sep);
  out.line.i32(hi);
  out.line.str_P(suffix);
  out.send();
}

static void err_full() {
  out.begin();
  out.line.str_P(PSTR("ERR FULL "));
  out.line.u32(PROGRAMME_MAX);
  out.line.str_P(PSTR(" items"));
  out.send();
}

// "<word> <p_0> ... <p_{AXES-1}>": every axis's position (one value on a one-axis rig, as in 2.1.0).
static void word_positions(const char *word) {
  out.begin();
  out.line.str_P(word);
  for (uint8_t a = 0; a < AXES; a++) {
    out.line.put(' ');
    out.line.i32(read_position(a));
  }
  out.send();
}

// The first axis the programme would take outside -its release..its travel from the present positions, or -1.
static int8_t programme_leaves_travel() {
  for (uint8_t a = 0; a < AXES; a++) {
    int16_t pos = read_position(a);
    for (uint8_t i = 0; i < prog_len; i++) {
      if (prog[i].kind != ITEM_SEG) continue;
      int16_t n = prog[i].n[a];
      pos += (prog[i].release & (1 << a)) ? -n : n;
      if (pos < -(int16_t)rig_axis_release[a] || pos > (int16_t)rig_axis_travel[a]) return (int8_t)a;
    }
  }
  return -1;
}

static bool editable() {
  if (running) {
    out.err(PSTR("STATE"), PSTR("running"));
    return false;
  }
#if AXES > 1
  if (stream_state) {  // the stream's state takes the programme table's RAM
    out.err(PSTR("STATE"), PSTR("streaming"));
    return false;
  }
#endif
  return true;
}

static Item *new_item() {
  if (prog_len >= PROGRAMME_MAX) {
    err_full();
    return 0;
  }
  Item *it = &prog[prog_len++];
  for (uint8_t a = 0; a < AXES; a++) it->n[a] = 0;
  it->release = 0;
  return it;
}

// Queues one period's set-points (V, MV) and replies with the period they drive, or ERR FULL.
static void queue_setpoints(const int16_t *vs, const char *word) {
  cli();
  if (fifo_count >= SETPOINT_FIFO) {
    sei();
    return out.err(PSTR("FULL"), PSTR("8 set-points queued"));
  }
  uint32_t period = next_period + fifo_count;
  int16_t *slot = st.fifo[(fifo_head + fifo_count) & (SETPOINT_FIFO - 1)];
  for (uint8_t a = 0; a < AXES; a++) slot[a] = vs[a];
  fifo_count++;
  sei();
  out.word_u32(word, period);
}

static void handle(Command *cmd) {
  if (proto_is(cmd, PSTR("PING"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("PING takes no argument"));
    out.text(PSTR("PONG stepper " FW_ID));
  } else if (proto_is(cmd, PSTR("CLEAR"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("CLEAR takes no argument"));
    if (!editable()) return;
    prog_len = 0;
    out.text(PSTR("OK CLEAR"));
  } else if (proto_is(cmd, PSTR("SEG"))) {
    if (!proto_args_ok(cmd, 3)) return out.err(PSTR("ARG"), PSTR("SEG needs 3 integers"));
    if (!editable()) return;
    int32_t dir = cmd->arg[0], n = cmd->arg[1], iv = cmd->arg[2];
    if (dir != 1 && dir != -1) return out.err(PSTR("RANGE"), PSTR("dir must be 1 or -1"));
    int32_t span0 = (int32_t)rig_axis_travel[0] + rig_axis_release[0];  // release + travel: the most one item moves axis 0
    if (n < 1 || n > span0) return err_range(PSTR("n_steps "), 1, PSTR("-"), span0, PSTR(""));
    if (iv < INTERVAL_MIN_US || iv > INTERVAL_MAX_US)
      return err_range(PSTR("interval "), INTERVAL_MIN_US, PSTR("-"), INTERVAL_MAX_US, PSTR(" us"));
    Item *it = new_item();
    if (!it) return;
    it->kind = ITEM_SEG;
    it->n[0] = (uint8_t)n;
    it->release = dir < 0 ? 1 : 0;
    it->ticks = (uint32_t)iv * 2 * (uint32_t)n;
    out.word_i32(PSTR("OK SEG"), prog_len);
  } else if (proto_is(cmd, PSTR("MSEG"))) {
    // MSEG <window_us> <n_0> ... <n_{AXES-1}>: every axis a moves n_a steps (signed: + pulls) in the window
    if (!proto_args_ok(cmd, 1 + AXES)) {
      out.begin();
      out.line.str_P(PSTR("ERR ARG MSEG needs "));
      out.line.u32(1 + AXES);
      out.line.str_P(PSTR(" integers"));
      return out.send();
    }
    if (!editable()) return;
    int32_t window = cmd->arg[0];
    if (window < 1 || window > 255L * INTERVAL_MAX_US)
      return err_range(PSTR("window "), 1, PSTR("-"), 255L * INTERVAL_MAX_US, PSTR(" us"));
    uint8_t moving = 0;
    for (uint8_t a = 0; a < AXES; a++) {
      int32_t n = cmd->arg[1 + a];
      int32_t m = n < 0 ? -n : n;
      int32_t span = (int32_t)rig_axis_travel[a] + rig_axis_release[a];  // the farthest one item can go
      if (m > span) {
        out.begin();
        out.line.str_P(PSTR("ERR RANGE axis "));
        out.line.u32(a);
        out.line.str_P(PSTR(" steps -"));
        out.line.u32(span);
        out.line.put('.');
        out.line.put('.');
        out.line.u32(span);
        return out.send();
      }
      // each moving axis steps every window / |n| us on average, within the interval limits
      if (m && (window < m * INTERVAL_MIN_US || window > m * INTERVAL_MAX_US)) {
        out.begin();
        out.line.str_P(PSTR("ERR RANGE axis "));
        out.line.u32(a);
        out.line.str_P(PSTR(" interval "));
        out.line.i32(INTERVAL_MIN_US);
        out.line.put('-');
        out.line.i32(INTERVAL_MAX_US);
        out.line.str_P(PSTR(" us"));
        return out.send();
      }
      if (m) moving = 1;
    }
    if (!moving) return out.err(PSTR("RANGE"), PSTR("no axis moves (a dwell is WAIT)"));
    Item *it = new_item();
    if (!it) return;
    it->kind = ITEM_SEG;
    for (uint8_t a = 0; a < AXES; a++) {
      int32_t n = cmd->arg[1 + a];
      it->n[a] = (uint8_t)(n < 0 ? -n : n);
      if (n < 0) it->release |= (uint8_t)(1 << a);
    }
    it->ticks = (uint32_t)window * 2;
    out.word_i32(PSTR("OK MSEG"), prog_len);
  } else if (proto_is(cmd, PSTR("WAIT"))) {
    if (!proto_args_ok(cmd, 1)) return out.err(PSTR("ARG"), PSTR("WAIT needs 1 integer"));
    if (!editable()) return;
    int32_t ms = cmd->arg[0];
    if (ms < 0 || ms > DWELL_MAX_MS) return out.err(PSTR("RANGE"), PSTR("dwell 0-60000 ms"));
    Item *it = new_item();
    if (!it) return;
    it->kind = ITEM_WAIT;
    it->ticks = (uint32_t)ms * 2000UL;
    out.word_i32(PSTR("OK WAIT"), prog_len);
  } else if (proto_is(cmd, PSTR("GO"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("GO takes no argument"));
    if (running) return out.err(PSTR("STATE"), PSTR("running"));
    if (stream_state) return out.err(PSTR("STATE"), PSTR("streaming"));
    if (prog_len == 0) return out.err(PSTR("STATE"), PSTR("programme empty"));
    if (!enabled) return out.err(PSTR("STATE"), PSTR("driver disabled"));
    int8_t bad = programme_leaves_travel();
    if (bad >= 0) {
      out.begin();
      out.line.str_P(PSTR("ERR RANGE "));
      if (AXES > 1) {
        out.line.str_P(PSTR("axis "));
        out.line.u32((uint8_t)bad);
        out.line.put(' ');
      }
      out.line.str_P(PSTR("travel "));
      if (rig_axis_release[bad]) out.line.put('-');  // "-78-156"; without a release "0-156" as before
      out.line.u32(rig_axis_release[bad]);
      out.line.put('-');
      out.line.u32(rig_axis_travel[bad]);
      out.line.str_P(PSTR(" steps"));
      return out.send();
    }
    out.word_i32(PSTR("OK GO"), prog_len);  // queued before DONE can be
    run_go();
  } else if (proto_is(cmd, PSTR("ABORT"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("ABORT takes no argument"));
    run_abort();
    word_positions(PSTR("ABORTED"));
  } else if (proto_is(cmd, PSTR("CONFIG"))) {
    // CONFIG -> OK CONFIG <axes> <programme_max> <min_interval_us> <max_interval_us> <travel_0> ...
    //           [<release_0> ...]: every axis's release appended when the build has one (RIG_HAS_RELEASE)
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("CONFIG takes no argument"));
    out.begin();
    out.line.str_P(PSTR("OK CONFIG "));
    out.line.u32(AXES);
    out.line.put(' ');
    out.line.u32(PROGRAMME_MAX);
    out.line.put(' ');
    out.line.i32(INTERVAL_MIN_US);
    out.line.put(' ');
    out.line.i32(INTERVAL_MAX_US);
    for (uint8_t a = 0; a < AXES; a++) {
      out.line.put(' ');
      out.line.u32(rig_axis_travel[a]);
    }
    for (uint8_t a = 0; RIG_HAS_RELEASE && a < AXES; a++) {
      out.line.put(' ');
      out.line.u32(rig_axis_release[a]);
    }
    out.send();
  } else if (proto_is(cmd, PSTR("EN"))) {
    if (!proto_args_ok(cmd, 1)) return out.err(PSTR("ARG"), PSTR("EN needs 1 integer"));
    int32_t on = cmd->arg[0];
    if (on != 0 && on != 1) return out.err(PSTR("RANGE"), PSTR("EN 0 or 1"));
    if (on) {
      PORTD &= ~ENA_BIT;
      enabled = 1;
    } else {
      run_abort();  // stops a running programme first, then disables
    }
    out.word_i32(PSTR("OK EN"), on);
  } else if (proto_is(cmd, PSTR("POS"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("POS takes no argument"));
    word_positions(PSTR("OK POS"));
  } else if (proto_is(cmd, PSTR("MEM"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("MEM takes no argument"));
    out.word_u32(PSTR("OK MEM"), free_stack_min());
  } else if (proto_is(cmd, PSTR("SHAPER"))) {
    if (!proto_args_ok(cmd, 2)) return out.err(PSTR("ARG"), PSTR("SHAPER needs 2 integers"));
    if (stream_state) return out.err(PSTR("STATE"), PSTR("streaming"));
    int32_t n = cmd->arg[0], neg = cmd->arg[1];
    if (n < 1 || n > SP_MAX_IMPULSES) return out.err(PSTR("RANGE"), PSTR("1-8 impulses"));
    if (neg != 0 && neg != 1) return out.err(PSTR("RANGE"), PSTR("negative amplitudes 0 or 1"));
    shaper_ready = 0;
    shaper_expect = (uint8_t)n;
    shaper_next = 0;
    shaper_neg = (uint8_t)neg;
    shaper_sum = 0;
    out.word_i32(PSTR("OK SHAPER"), n);
  } else if (proto_is(cmd, PSTR("IMP"))) {
    if (!proto_args_ok(cmd, 3)) return out.err(PSTR("ARG"), PSTR("IMP needs 3 integers"));
    if (stream_state) return out.err(PSTR("STATE"), PSTR("streaming"));
    if (!shaper_expect || cmd->arg[0] != shaper_next) return out.err(PSTR("STATE"), PSTR("SHAPER first, impulses in order"));
    SpShaper &pl = sp_shaper;
    uint8_t i = shaper_next;
    int32_t previous_us = i ? (int32_t)pl.d[i - 1] * SP_DELAY_UNIT_US : -1;
    uint8_t bad = sp_check_impulse(i, cmd->arg[1], cmd->arg[2], previous_us, shaper_neg);
    if (bad) {
      shaper_expect = 0;  // the shaper is discarded: start again with SHAPER
      if (bad == 1) return out.err(PSTR("RANGE"), PSTR("amplitude -16384..16384 (>= 0 unless allowed)"));
      return out.err(PSTR("RANGE"), PSTR(SP_MAX_DELAY_TEXT));
    }
    pl.a[i] = (int16_t)cmd->arg[1];
    pl.d[i] = (uint16_t)(cmd->arg[2] / SP_DELAY_UNIT_US);
    shaper_sum += cmd->arg[1];
    shaper_next = (uint8_t)(i + 1);
    if (shaper_next == shaper_expect) {
      shaper_expect = 0;
      if (shaper_sum != SP_AMP_ONE) return out.err(PSTR("RANGE"), PSTR("amplitudes must sum to 4096"));
      pl.n = shaper_next;
      shaper_ready = 1;
    }
    out.word_i32(PSTR("OK IMP"), i);
  } else if (proto_is(cmd, PSTR("STREAM"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("STREAM takes no argument"));
    if (running) return out.err(PSTR("STATE"), PSTR("running"));
    if (stream_state) return out.err(PSTR("STATE"), PSTR("streaming"));
    if (!shaper_ready) return out.err(PSTR("STATE"), PSTR("no shaper"));
    if (!enabled) return out.err(PSTR("STATE"), PSTR("driver disabled"));
#if AXES > 1
    prog_len = 0;  // the stream's state takes the programme table's RAM
#endif
    out.word_i32(PSTR("OK STREAM"), read_position());  // queued before the stream's first line
    stream_start();
  } else if (proto_is(cmd, PSTR("V"))) {
    // V <v>: axis 0's set-point (the other axes' zero)
    if (!proto_args_ok(cmd, 1)) return out.err(PSTR("ARG"), PSTR("V needs 1 integer"));
    if (stream_state != ST_ACTIVE) return out.err(PSTR("STATE"), PSTR("not streaming"));
    int32_t v = cmd->arg[0];
    if (v < -SP_V_MAX || v > SP_V_MAX) return err_range(PSTR("set-point "), -SP_V_MAX, PSTR(".."), SP_V_MAX, PSTR(""));
    int16_t vs[AXES];
    vs[0] = (int16_t)v;
    for (uint8_t a = 1; a < AXES; a++) vs[a] = 0;
    queue_setpoints(vs, PSTR("OK V"));
  } else if (proto_is(cmd, PSTR("MV"))) {
    // MV <v_0> ... <v_{AXES-1}>: every axis's set-point
    if (!proto_args_ok(cmd, AXES)) {
      out.begin();
      out.line.str_P(PSTR("ERR ARG MV needs "));
      out.line.u32(AXES);
      out.line.str_P(AXES > 1 ? PSTR(" integers") : PSTR(" integer"));
      return out.send();
    }
    if (stream_state != ST_ACTIVE) return out.err(PSTR("STATE"), PSTR("not streaming"));
    int16_t vs[AXES];
    for (uint8_t a = 0; a < AXES; a++) {
      int32_t v = cmd->arg[a];
      if (v < -SP_V_MAX || v > SP_V_MAX) {
        out.begin();
        out.line.str_P(PSTR("ERR RANGE axis "));
        out.line.u32(a);
        out.line.str_P(PSTR(" set-point "));
        out.line.i32(-SP_V_MAX);
        out.line.str_P(PSTR(".."));
        out.line.i32(SP_V_MAX);
        return out.send();
      }
      vs[a] = (int16_t)v;
    }
    queue_setpoints(vs, PSTR("OK MV"));
  } else if (proto_is(cmd, PSTR("END"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("END takes no argument"));
    if (stream_state != ST_ACTIVE) return out.err(PSTR("STATE"), PSTR("not streaming"));
    cli();
    uint32_t e = next_period + fifo_count;
    end_period = e;
    stream_state = ST_ENDING;
    sei();
    out.word_u32(PSTR("OK END"), e);
  } else {
    out.err(PSTR("UNKNOWN"), PSTR("command"));
  }
}

static LineReader reader;

static void service_done() {
  while (notice_count) {
    cli();
    uint8_t i = notice_head;
    uint8_t kind = notice_kind[i] & 0x0F, axis = notice_kind[i] >> 4;
    int32_t value = notice_value[i];
    notice_head = (uint8_t)((i + 1) & (NOTICES - 1));
    notice_count--;
    sei();
    out.begin();
    if (kind == NOTICE_SPEED) out.line.str_P(PSTR("N,LIMIT,SPEED,"));
    else if (kind == NOTICE_TRAVEL) out.line.str_P(PSTR("N,LIMIT,TRAVEL,"));
    else out.line.str_P(PSTR("N,WATCHDOG,"));
    out.line.i32(value);
    if (axis) {  // several axes: the notices of axes 1.. name their axis
      out.line.put(',');
      out.line.u32(axis);
    }
    out.send();
  }
  if (done_flag) {
    done_flag = 0;
    word_positions(PSTR("DONE"));
  }
}

void setup() {
  PORTD |= ENA_BIT;  // driver disabled (also done in .init3)
  DDRD |= ENA_BIT | DIR_BIT | all_step_bits();
  PORTD &= (uint8_t)~(DIR_BIT | all_step_bits());
  DDRB |= dir_bits_b();
  PORTB &= (uint8_t)~dir_bits_b();
  DDRB |= TP_TICK_BIT | TP_STEP_BIT;
  PORTB &= ~(TP_TICK_BIT | TP_STEP_BIT);
  Serial.begin(RIG_STEPPER_BAUD);
  // Timer0's overflow interrupt (millis/micros, unused here) would delay step edges by up to ~5 us.
  TIMSK0 = 0;
  reader.reset();
  out.text(PSTR("HELLO stepper " FW_ID));
}

void loop() {
  service_done();
  while (Serial.available() > 0) {
    LineEvent ev = reader.feed((char)Serial.read());
    if (ev == LINE_NONE) continue;
    service_done();  // an unsolicited DONE goes out before the reply to a later command
    if (ev == LINE_TOOLONG) {
      out.err(PSTR("TOOLONG"), PSTR("line over 63 characters"));
    } else {
      Command cmd;
      if (!out.refused(proto_parse(reader.buf, reader.len, &cmd))) handle(&cmd);
    }
    reader.reset();
  }
}
