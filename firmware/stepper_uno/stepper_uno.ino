// Stepper board: Arduino Uno driving a TB6600 on STEP = D5, DIR = D6 (HIGH = pull), ENA = D7 (HIGH disables).
// Stores a programme of segments and dwells and runs it with Timer1 step timing. Protocol:
// firmware/PROTOCOL.md (115200 baud, 8N1).
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
// Safety: the compiled-in limits below are enforced whatever the host asks; the driver is disabled at reset
// (ENA is driven HIGH in .init3, before the C runtime starts), on ABORT and on EN 0.

#include <avr/interrupt.h>
#include <avr/io.h>

#include "proto.h"
#include "reply.h"

#define FW_VERSION "2.0.0"

// Compiled-in limits (PROTOCOL.md table).
static const int32_t INTERVAL_MIN_US = 639;       // 400 mm/s at 0.25525 mm/step
static const int32_t INTERVAL_MAX_US = 1000000;   // one step per second
static const int16_t TRAVEL_MAX_STEPS = 156;      // 40 mm at 0.25525 mm/step, from zero
static const int32_t DWELL_MAX_MS = 60000;
#define PROGRAMME_MAX 64

// The STEP edge is issued this many 0.5 us ticks after the compare match (longer than any other ISR).
static const uint16_t STEP_LEAD_TICKS = 16;

// STEP = D5 = PD5, DIR = D6 = PD6, ENA = D7 = PD7.
#define STEP_BIT _BV(PD5)
#define DIR_BIT _BV(PD6)
#define ENA_BIT _BV(PD7)

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
static uint8_t prog_len;

// Run state (ISR-owned while running).
static volatile uint8_t running;
static volatile uint8_t done_flag;    // one byte: set by the ISR, cleared by the main loop
static volatile int16_t position;     // steps from zero, + for pulls
static uint8_t cur;                   // index of the item in progress
static uint8_t steps_left;            // steps still to issue in the current segment
static uint32_t rem_ticks;            // ticks still to wait after the present chunk
static uint8_t enabled;               // driver enabled (ENA LOW)

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

ISR(TIMER1_COMPA_vect) {
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

static void run_abort() {
  cli();
  timer_stop();
  running = 0;
  done_flag = 0;
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
  if (proto_is(cmd, "PING")) {
    if (!proto_args_ok(cmd, 0)) return out.err("ARG", "PING takes no argument");
    out.text("PONG stepper " FW_VERSION);
  } else if (proto_is(cmd, "CLEAR")) {
    if (!proto_args_ok(cmd, 0)) return out.err("ARG", "CLEAR takes no argument");
    if (running) return out.err("STATE", "running");
    prog_len = 0;
    out.text("OK CLEAR");
  } else if (proto_is(cmd, "SEG")) {
    if (!proto_args_ok(cmd, 3)) return out.err("ARG", "SEG needs 3 integers");
    if (running) return out.err("STATE", "running");
    int32_t dir = cmd->arg[0], n = cmd->arg[1], iv = cmd->arg[2];
    if (dir != 1 && dir != -1) return out.err("RANGE", "dir must be 1 or -1");
    if (n < 1 || n > TRAVEL_MAX_STEPS) return out.err("RANGE", "n_steps 1-156");
    if (iv < INTERVAL_MIN_US || iv > INTERVAL_MAX_US) return out.err("RANGE", "interval 639-1000000 us");
    if (prog_len >= PROGRAMME_MAX) return out.err("FULL", "64 items");
    Item &it = prog[prog_len++];
    it.kind = ITEM_SEG;
    it.dir = (int8_t)dir;
    it.n_steps = (uint8_t)n;
    it.ticks = (uint32_t)iv * 2;
    out.word_i32("OK SEG", prog_len);
  } else if (proto_is(cmd, "WAIT")) {
    if (!proto_args_ok(cmd, 1)) return out.err("ARG", "WAIT needs 1 integer");
    if (running) return out.err("STATE", "running");
    int32_t ms = cmd->arg[0];
    if (ms < 0 || ms > DWELL_MAX_MS) return out.err("RANGE", "dwell 0-60000 ms");
    if (prog_len >= PROGRAMME_MAX) return out.err("FULL", "64 items");
    Item &it = prog[prog_len++];
    it.kind = ITEM_WAIT;
    it.dir = 0;
    it.n_steps = 0;
    it.ticks = (uint32_t)ms * 2000UL;
    out.word_i32("OK WAIT", prog_len);
  } else if (proto_is(cmd, "GO")) {
    if (!proto_args_ok(cmd, 0)) return out.err("ARG", "GO takes no argument");
    if (running) return out.err("STATE", "running");
    if (prog_len == 0) return out.err("STATE", "programme empty");
    if (!enabled) return out.err("STATE", "driver disabled");
    if (!programme_within_travel(read_position())) return out.err("RANGE", "travel 0-156 steps");
    out.word_i32("OK GO", prog_len);  // queued before DONE can be
    run_go();
  } else if (proto_is(cmd, "ABORT")) {
    if (!proto_args_ok(cmd, 0)) return out.err("ARG", "ABORT takes no argument");
    run_abort();
    out.word_i32("ABORTED", read_position());
  } else if (proto_is(cmd, "EN")) {
    if (!proto_args_ok(cmd, 1)) return out.err("ARG", "EN needs 1 integer");
    int32_t on = cmd->arg[0];
    if (on != 0 && on != 1) return out.err("RANGE", "EN 0 or 1");
    if (on) {
      PORTD &= ~ENA_BIT;
      enabled = 1;
    } else {
      run_abort();  // stops a running programme first, then disables
    }
    out.word_i32("OK EN", on);
  } else if (proto_is(cmd, "POS")) {
    if (!proto_args_ok(cmd, 0)) return out.err("ARG", "POS takes no argument");
    out.word_i32("OK POS", read_position());
  } else {
    out.err("UNKNOWN", "command");
  }
}

static LineReader reader;

static void service_done() {
  if (done_flag) {
    done_flag = 0;
    out.word_i32("DONE", read_position());
  }
}

void setup() {
  PORTD |= ENA_BIT;  // driver disabled (also done in .init3)
  DDRD |= ENA_BIT | STEP_BIT | DIR_BIT;
  PORTD &= ~(STEP_BIT | DIR_BIT);
  Serial.begin(115200);
  // Timer0's overflow interrupt (millis/micros, unused here) would delay step edges by up to ~5 us.
  TIMSK0 = 0;
  reader.reset();
  out.text("HELLO stepper " FW_VERSION);
}

void loop() {
  service_done();
  while (Serial.available() > 0) {
    LineEvent ev = reader.feed((char)Serial.read());
    if (ev == LINE_NONE) continue;
    service_done();  // an unsolicited DONE goes out before the reply to a later command
    if (ev == LINE_TOOLONG) {
      out.err("TOOLONG", "line over 63 characters");
    } else {
      Command cmd;
      ProtoStatus st = proto_parse(reader.buf, reader.len, &cmd);
      if (st == PROTO_CHECKSUM) out.err("CHECKSUM", "bad checksum");
      else if (st == PROTO_OK) handle(&cmd);
    }
    reader.reset();
  }
}
