// Stepper board: Arduino Uno driving a TB6600 on STEP = D5, DIR = D6 (HIGH = pull), ENA = D7 (HIGH disables).
// Two modes, both with Timer1 step timing: a stored programme of segments and dwells (GO), and a stream of
// velocity set-points shaped on the board by one loaded input shaper (STREAM). Protocol: firmware/PROTOCOL.md
// (115200 baud, 8N1).
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
// planned steps from a queue, each STEP edge a fixed 16 us after its compare match (8 us in programme mode).
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
#include "stream_plan.h"

#define FW_VERSION "2.1.0"

// Compiled-in limits (PROTOCOL.md table).
static const int32_t INTERVAL_MIN_US = 639;       // 400 mm/s at 0.25525 mm/step
static const int32_t INTERVAL_MAX_US = 1000000;   // one step per second
static const int16_t TRAVEL_MAX_STEPS = 156;      // 40 mm at 0.25525 mm/step, from zero
static const int32_t DWELL_MAX_MS = 60000;
#define PROGRAMME_MAX 64

// The STEP edge is issued this many 0.5 us ticks after the compare match (longer than any other ISR).
static const uint16_t STEP_LEAD_TICKS = 16;
// Streaming: 16 us, since the control tick's short interrupt-free sections add to the UART's.
static const uint16_t STREAM_STEP_LEAD_TICKS = 32;

// STEP = D5 = PD5, DIR = D6 = PD6, ENA = D7 = PD7.
#define STEP_BIT _BV(PD5)
#define DIR_BIT _BV(PD6)
#define ENA_BIT _BV(PD7)
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

struct Item {
  uint32_t ticks;   // SEG: interval between steps; WAIT: the dwell; in 0.5 us ticks
  uint8_t n_steps;  // SEG only (<= TRAVEL_MAX_STEPS)
  int8_t dir;       // SEG only: +1 pull, -1 release
  uint8_t kind;
};

static Item prog[PROGRAMME_MAX];

// Streaming state (PROTOCOL.md "Streaming"): the planner with its shaper and set-point history, the queue of
// planned steps and the set-point FIFO. (About 430 bytes: it fits beside the programme table since the boards'
// constant strings are kept in flash.)
#define STEP_QUEUE 32  // planned steps not yet emitted: at most 16 per 10 ms period, two periods ahead
#define SETPOINT_FIFO 8
struct StreamMem {
  Planner planner;
  uint16_t step_time[STEP_QUEUE];   // Timer1 value (ticks from STREAM, mod 2^16) of each queued step
  uint8_t step_up[STEP_QUEUE / 8];  // bit set: the step is a pull (+1)
  int16_t fifo[SETPOINT_FIFO];      // set-points received and not yet taken by a control tick
};
static StreamMem st;
static uint8_t prog_len;

// Run state (ISR-owned while running).
static volatile uint8_t running;
static volatile uint8_t done_flag;    // one byte: set by the ISR, cleared by the main loop
static volatile int16_t position;     // steps from zero, + for pulls
static uint8_t cur;                   // index of the item in progress
static uint8_t steps_left;            // steps still to issue in the current segment
static uint32_t rem_ticks;            // ticks still to wait after the present chunk
static volatile uint8_t enabled;      // driver enabled (ENA LOW); the stream watchdog may clear it

static void timer_stop() {
  TCCR1B = 0;
  TIMSK1 = 0;
}

// Loads the wait until the next event (called just after a compare match, or with the timer stopped):
// OCR1A = period - 1; a wait over 65536 ticks starts with a chunk of 32768 and the ISR loads the rest.
static void schedule(uint32_t ticks) {
  if (ticks > 65536UL) {
    OCR1A = 32768 - 1;
    rem_ticks = ticks - 32768;
  } else {
    OCR1A = (uint16_t)(ticks - 1);
    rem_ticks = 0;
  }
}

static void set_dir(int8_t dir) {
  if (dir > 0) PORTD |= DIR_BIT;
  else PORTD &= ~DIR_BIT;
}

// Starts item `cur` at the present event time (skipping zero-length dwells); finishes after the last one.
static void start_item() {
  while (cur < prog_len) {
    Item &it = prog[cur];
    if (it.kind == ITEM_SEG) {
      set_dir(it.dir);
      steps_left = it.n_steps;
      schedule(it.ticks);
      return;
    }
    if (it.ticks > 0) {
      schedule(it.ticks);
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

ISR(TIMER1_COMPA_vect) {
  if (stream_timer) {
    stream_step_isr();
    return;
  }
  if (rem_ticks) {
    uint32_t r = rem_ticks;
    if (r > 65536UL) {
      OCR1A = 32767;
      rem_ticks = r - 32768;
    } else {
      OCR1A = (uint16_t)(r - 1);
      rem_ticks = 0;
    }
    return;
  }
  Item &it = prog[cur];
  if (it.kind == ITEM_SEG) {
    // The step edge at a fixed STEP_LEAD_TICKS after the compare match, whatever the interrupt latency
    // (another ISR may delay this one by a few us): every step is late by the same 8 us.
    while (TCNT1 < STEP_LEAD_TICKS) {
    }
    PORTD |= STEP_BIT;
    position += it.dir;
    __builtin_avr_delay_cycles(64);  // TB6600 needs >= 2.5 us high; with the code around it ~5 us
    PORTD &= ~STEP_BIT;
    if (--steps_left) {
      if (it.ticks > 65536UL) schedule(it.ticks);  // short intervals: OCR1A already holds the period
      return;
    }
  }
  cur++;
  start_item();
}

// ---------------------------------------------------------------------------------------------------------
// Streaming (PROTOCOL.md "Streaming"): a FIFO of set-points, the control tick (Timer1 compare B, 100 Hz) that
// plans one period at a time, and the step queue that compare A empties.

enum StreamState : uint8_t { ST_IDLE = 0, ST_ACTIVE, ST_ENDING, ST_WATCHDOG };
static const uint8_t WATCHDOG_PERIODS = 10;  // 100 ms without a set-point

static volatile uint8_t stream_state;
static volatile uint8_t sq_head, sq_count;        // the step queue: the control tick adds, compare A takes
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
static uint8_t shaper_ready;   // a complete, valid shaper is in st.planner
static uint8_t shaper_expect;  // impulses announced by SHAPER; 0 when not loading
static uint8_t shaper_next;    // the index the next IMP must have
static uint8_t shaper_neg;     // negative amplitudes allowed
static int32_t shaper_sum;

// notices, queued by the control tick and sent by the main loop
enum NoticeKind : uint8_t { NOTICE_SPEED = SP_NOTICE_SPEED, NOTICE_TRAVEL = SP_NOTICE_TRAVEL, NOTICE_WATCHDOG };
#define NOTICES 4
static uint8_t notice_kind[NOTICES];
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

void sp_notice(uint8_t kind, int32_t value) { push_notice(kind, value); }

static inline uint8_t step_is_up(uint8_t i) { return st.step_up[i >> 3] & (uint8_t)(1 << (i & 7)); }

static inline void set_dir_for(uint8_t i) {
  if (step_is_up(i)) PORTD |= DIR_BIT;
  else PORTD &= ~DIR_BIT;
}

// Queues one planned step (called by the planner from the control tick, interrupts enabled).
void sp_emit_step(uint32_t tick, int8_t dir) {
  uint8_t sreg = SREG;
  cli();
  if (sq_count >= STEP_QUEUE) {
    queue_overflow = 1;
    SREG = sreg;
    return;
  }
  uint8_t i = (uint8_t)((sq_head + sq_count) & (STEP_QUEUE - 1));
  st.step_time[i] = (uint16_t)tick;
  if (dir > 0) st.step_up[i >> 3] |= (uint8_t)(1 << (i & 7));
  else st.step_up[i >> 3] &= (uint8_t)~(1 << (i & 7));
  if (sq_count++ == 0) {  // the step generator was idle: arm it (DIR set at least 8 ms before this step)
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
  uint8_t i = sq_head;
  uint16_t edge = OCR1A + STREAM_STEP_LEAD_TICKS;
  while ((int16_t)(TCNT1 - edge) < 0) {
  }
  PORTD |= STEP_BIT;
  position += step_is_up(i) ? 1 : -1;
  __builtin_avr_delay_cycles(64);  // TB6600 needs >= 2.5 us high
  PORTD &= ~STEP_BIT;
  i = (uint8_t)((i + 1) & (STEP_QUEUE - 1));
  sq_head = i;
  if (--sq_count) {
    set_dir_for(i);  // at least 600 us before its step (steps are 639 us apart or more)
    OCR1A = st.step_time[i];
  } else {
    TIMSK1 &= ~_BV(OCIE1A);
  }
  PORTB &= ~TP_STEP_BIT;
}

static void stream_stop_timer() {
  timer_stop();
  stream_timer = 0;
  stream_state = ST_IDLE;
  finishing = 0;
  sq_count = 0;
  fifo_count = 0;
}

// The control tick: takes the set-point of the next period and plans it. Runs with interrupts enabled, so the
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
  int16_t v;
  uint8_t state = stream_state;
  if (fifo_count) {
    v = st.fifo[fifo_head];
    fifo_head = (uint8_t)((fifo_head + 1) & (SETPOINT_FIFO - 1));
    fifo_count--;
    underruns = 0;
  } else if (state == ST_ACTIVE) {
    if (++underruns > WATCHDOG_PERIODS) {  // the stream stopped: feed zero from now on
      stream_state = state = ST_WATCHDOG;
      end_period = k;
      v = 0;
      push_notice(NOTICE_WATCHDOG, (int32_t)k);
    } else {
      v = 0;  // an underrun: the period moves nothing (2.1.0; 2.0.0 held the last set-point, moving the
              // cable further than commanded whenever the host was late)
    }
  } else {
    v = 0;
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
    if (v) last_nonzero = k;
    if (!finishing && state != ST_ACTIVE && k >= end_period &&
        k - last_nonzero >= (uint32_t)st.planner.q_max + 2) {
      finishing = 1;  // every impulse now sees zero: the last step is planned
      finish_at = k + 3;
    }
  }
  PORTB &= ~TP_TICK_BIT;
  tick_busy = 0;
}

static int16_t read_position();

static void stream_start() {
  st.planner.start(read_position());  // the timer is stopped: nothing else touches the planner
  cli();
  timer_stop();
  sq_head = sq_count = 0;
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

static int16_t read_position() {
  cli();
  int16_t p = position;
  sei();
  return p;
}

static void run_go() {
  cli();
  cur = 0;
  running = 1;
  done_flag = 0;
  TCCR1A = 0;
  TCCR1B = 0;
  TCNT1 = 0;
  TIFR1 = _BV(OCF1A);
  start_item();  // t0 = now; sets OCR1A for the first event
  if (running) {
    TIMSK1 = _BV(OCIE1A);
    TCCR1B = _BV(WGM12) | _BV(CS11);  // CTC on OCR1A, clk/8: 0.5 us ticks
  }
  sei();
}

// ---------------------------------------------------------------------------------------------------------
// Output

static void serial_write(const uint8_t *buf, uint8_t n) { Serial.write(buf, n); }

static Reply out = {{}, serial_write};

// ---------------------------------------------------------------------------------------------------------
// Commands

// Would the programme stay within 0..TRAVEL_MAX_STEPS starting from `pos`?
static bool programme_within_travel(int16_t pos) {
  for (uint8_t i = 0; i < prog_len; i++) {
    if (prog[i].kind != ITEM_SEG) continue;
    pos += prog[i].dir * (int16_t)prog[i].n_steps;
    if (pos < 0 || pos > TRAVEL_MAX_STEPS) return false;
  }
  return true;
}

static void handle(Command *cmd) {
  if (proto_is(cmd, PSTR("PING"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("PING takes no argument"));
    out.text(PSTR("PONG stepper " FW_VERSION));
  } else if (proto_is(cmd, PSTR("CLEAR"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("CLEAR takes no argument"));
    if (running) return out.err(PSTR("STATE"), PSTR("running"));
    prog_len = 0;
    out.text(PSTR("OK CLEAR"));
  } else if (proto_is(cmd, PSTR("SEG"))) {
    if (!proto_args_ok(cmd, 3)) return out.err(PSTR("ARG"), PSTR("SEG needs 3 integers"));
    if (running) return out.err(PSTR("STATE"), PSTR("running"));
    int32_t dir = cmd->arg[0], n = cmd->arg[1], iv = cmd->arg[2];
    if (dir != 1 && dir != -1) return out.err(PSTR("RANGE"), PSTR("dir must be 1 or -1"));
    if (n < 1 || n > TRAVEL_MAX_STEPS) return out.err(PSTR("RANGE"), PSTR("n_steps 1-156"));
    if (iv < INTERVAL_MIN_US || iv > INTERVAL_MAX_US) return out.err(PSTR("RANGE"), PSTR("interval 639-1000000 us"));
    if (prog_len >= PROGRAMME_MAX) return out.err(PSTR("FULL"), PSTR("64 items"));
    Item &it = prog[prog_len++];
    it.kind = ITEM_SEG;
    it.dir = (int8_t)dir;
    it.n_steps = (uint8_t)n;
    it.ticks = (uint32_t)iv * 2;
    out.word_i32(PSTR("OK SEG"), prog_len);
  } else if (proto_is(cmd, PSTR("WAIT"))) {
    if (!proto_args_ok(cmd, 1)) return out.err(PSTR("ARG"), PSTR("WAIT needs 1 integer"));
    if (running) return out.err(PSTR("STATE"), PSTR("running"));
    int32_t ms = cmd->arg[0];
    if (ms < 0 || ms > DWELL_MAX_MS) return out.err(PSTR("RANGE"), PSTR("dwell 0-60000 ms"));
    if (prog_len >= PROGRAMME_MAX) return out.err(PSTR("FULL"), PSTR("64 items"));
    Item &it = prog[prog_len++];
    it.kind = ITEM_WAIT;
    it.dir = 0;
    it.n_steps = 0;
    it.ticks = (uint32_t)ms * 2000UL;
    out.word_i32(PSTR("OK WAIT"), prog_len);
  } else if (proto_is(cmd, PSTR("GO"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("GO takes no argument"));
    if (running) return out.err(PSTR("STATE"), PSTR("running"));
    if (stream_state) return out.err(PSTR("STATE"), PSTR("streaming"));
    if (prog_len == 0) return out.err(PSTR("STATE"), PSTR("programme empty"));
    if (!enabled) return out.err(PSTR("STATE"), PSTR("driver disabled"));
    if (!programme_within_travel(read_position())) return out.err(PSTR("RANGE"), PSTR("travel 0-156 steps"));
    out.word_i32(PSTR("OK GO"), prog_len);  // queued before DONE can be
    run_go();
  } else if (proto_is(cmd, PSTR("ABORT"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("ABORT takes no argument"));
    run_abort();
    out.word_i32(PSTR("ABORTED"), read_position());
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
    out.word_i32(PSTR("OK POS"), read_position());
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
    Planner &pl = st.planner;
    uint8_t i = shaper_next;
    int32_t previous_us = i ? (int32_t)pl.d[i - 1] * SP_DELAY_UNIT_US : -1;
    uint8_t bad = sp_check_impulse(i, cmd->arg[1], cmd->arg[2], previous_us, shaper_neg);
    if (bad) {
      shaper_expect = 0;  // the shaper is discarded: start again with SHAPER
      if (bad == 1) return out.err(PSTR("RANGE"), PSTR("amplitude -16384..16384 (>= 0 unless allowed)"));
      return out.err(PSTR("RANGE"), PSTR("delay: 0 first, rising, 16 us units, <= 1 s"));
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
    out.word_i32(PSTR("OK STREAM"), read_position());  // queued before the stream's first line
    stream_start();
  } else if (proto_is(cmd, PSTR("V"))) {
    if (!proto_args_ok(cmd, 1)) return out.err(PSTR("ARG"), PSTR("V needs 1 integer"));
    if (stream_state != ST_ACTIVE) return out.err(PSTR("STATE"), PSTR("not streaming"));
    int32_t v = cmd->arg[0];
    if (v < -SP_V_MAX || v > SP_V_MAX) return out.err(PSTR("RANGE"), PSTR("set-point -1640..1640"));
    cli();
    if (fifo_count >= SETPOINT_FIFO) {
      sei();
      return out.err(PSTR("FULL"), PSTR("8 set-points queued"));
    }
    uint32_t period = next_period + fifo_count;
    st.fifo[(fifo_head + fifo_count) & (SETPOINT_FIFO - 1)] = (int16_t)v;
    fifo_count++;
    sei();
    out.word_u32(PSTR("OK V"), period);
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
    uint8_t kind = notice_kind[i];
    int32_t value = notice_value[i];
    notice_head = (uint8_t)((i + 1) & (NOTICES - 1));
    notice_count--;
    sei();
    out.begin();
    if (kind == NOTICE_SPEED) out.line.str_P(PSTR("N,LIMIT,SPEED,"));
    else if (kind == NOTICE_TRAVEL) out.line.str_P(PSTR("N,LIMIT,TRAVEL,"));
    else out.line.str_P(PSTR("N,WATCHDOG,"));
    out.line.i32(value);
    out.send();
  }
  if (done_flag) {
    done_flag = 0;
    out.word_i32(PSTR("DONE"), read_position());
  }
}

void setup() {
  PORTD |= ENA_BIT;  // driver disabled (also done in .init3)
  DDRD |= ENA_BIT | STEP_BIT | DIR_BIT;
  PORTD &= ~(STEP_BIT | DIR_BIT);
  DDRB |= TP_TICK_BIT | TP_STEP_BIT;
  PORTB &= ~(TP_TICK_BIT | TP_STEP_BIT);
  Serial.begin(115200);
  // Timer0's overflow interrupt (millis/micros, unused here) would delay step edges by up to ~5 us.
  TIMSK0 = 0;
  reader.reset();
  out.text(PSTR("HELLO stepper " FW_VERSION));
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
