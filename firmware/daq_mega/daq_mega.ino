// DAQ board: Arduino Mega 2560. Samples the load-cell amplifier on A0 and counts the stepper driver's STEP
// pulses (with DIR), streaming both on one clock. Protocol: firmware/PROTOCOL.md (500000 baud, 8N1).
//
// Built by firmware/Makefile as C++ with `-include Arduino.h` (no IDE: functions are declared before use).
//
// Timing: Timer1 in CTC mode (/8, 0.5 us ticks) interrupts at the sample rate; its ISR starts one ADC
// conversion a fixed 16 us after the compare match (so interrupt latency does not jitter the sample
// instants) and takes the step count and the timestamp; the ADC-complete ISR stores the sample in a
// ring buffer. The main loop formats the ring's samples into lines and hands them to the serial TX buffer
// only when a whole line fits (it never waits for the UART), and answers commands. So the sampler never
// waits for the serial line: if the ring is full (the host link cannot keep up), the sample period is
// counted as missed and reported as `W,OVERRUN,<n>` before the next data line, never skipped silently.
//
// Pins: A0 = amplifier output (via the 150 ohm shunt), D2 = STEP (INT4, rising edge), D4 = DIR (HIGH = pull).

#include <avr/interrupt.h>
#include <avr/io.h>

#include "proto.h"
#include "reply.h"

#define FW_VERSION "2.1.0"

static const uint16_t RATE_MIN_HZ = 100;
static const uint16_t RATE_MAX_HZ = 2000;
static const uint16_t RATE_DEFAULT_HZ = 1000;
static const uint32_t TIMER1_HZ = 2000000UL;  // F_CPU / 8
static const uint16_t SAMPLE_LEAD_TICKS = 32;   // conversion start 16 us after the compare match

// ---------------------------------------------------------------------------------------------------------
// Sampler state (shared with the ISRs)

struct Sample {
  uint32_t t_us;
  int32_t steps;
  uint16_t adc;
  uint32_t missed_before;  // sample periods missed just before this sample (0 normally)
};

#define RING_SIZE 64  // power of two; 64 samples = 32 ms of slack at 2 kHz
static volatile Sample ring[RING_SIZE];
static volatile uint8_t ring_head;     // next slot the ADC ISR fills (written only by ISRs)
static volatile uint8_t ring_tail;     // next slot the main loop sends (written only by the main loop)
static volatile uint8_t conv_busy;     // a conversion started by the timer ISR is in progress
static volatile uint32_t missed;       // periods missed since the last sample taken
static volatile int32_t step_count;    // STEP pulses since ZERO, + for pulls

static uint8_t streaming;
static uint16_t rate_hz = RATE_DEFAULT_HZ;
static uint32_t n_sent;                // data lines sent since START (= next seq)

// STEP on D2 = PE4 = INT4 (rising edge); DIR on D4 = PG5, sampled on each pulse.
ISR(INT4_vect) {
  if (PING & _BV(PG5)) step_count++;
  else step_count--;
}

ISR(TIMER1_COMPA_vect) {
  uint8_t head = ring_head;
  if (conv_busy || (uint8_t)((head + 1) & (RING_SIZE - 1)) == ring_tail) {
    missed++;
    return;
  }
  // Start the conversion a fixed SAMPLE_LEAD_TICKS after the compare match, whatever the latency of this
  // interrupt (another ISR may delay it by a few us): the sample instants stay exactly one period apart.
  while (TCNT1 < SAMPLE_LEAD_TICKS) {
  }
  ADCSRA |= _BV(ADSC);
  volatile Sample &s = ring[head];
  s.steps = step_count;
  s.t_us = micros();
  s.missed_before = missed;
  missed = 0;
  conv_busy = 1;
}

ISR(ADC_vect) {
  uint8_t head = ring_head;
  ring[head].adc = ADC;
  ring_head = (uint8_t)((head + 1) & (RING_SIZE - 1));
  conv_busy = 0;
}

// ---------------------------------------------------------------------------------------------------------
// Output

// Blocking send, for replies (the sampler keeps running in its ISRs meanwhile).
static void serial_write(const uint8_t *buf, uint8_t n) { Serial.write(buf, n); }

static Reply out = {{}, serial_write};

// The next stream line, formatted once and kept until the TX buffer has room for all of it.
static LineWriter pending;
static uint8_t pending_len;     // 0: nothing formatted
static uint8_t pending_is_data; // the pending line is the tail sample's data line (else its overrun warning)

// Sends at most one stream line (a sample's overrun warning or its data line) if the whole line fits in the
// TX buffer, and returns at once otherwise: one per call, so that the main loop keeps reading commands
// even when the stream saturates the link.
static void service_stream() {
  if (!pending_len) {
    if (ring_tail == ring_head) return;
    volatile Sample &s = ring[ring_tail];
    pending.begin();
    if (s.missed_before) {
      pending.str_P(PSTR("W,OVERRUN,"));
      pending.u32(s.missed_before);
      pending_is_data = 0;
    } else {
      pending.str_P(PSTR("D,"));
      pending.u32(n_sent);
      pending.put(',');
      pending.u32(s.t_us);
      pending.put(',');
      pending.u32(s.adc);
      pending.put(',');
      pending.i32(s.steps);
      pending_is_data = 1;
    }
    pending_len = pending.finish();
  }
  if ((uint16_t)Serial.availableForWrite() < pending_len) return;
  Serial.write((const uint8_t *)pending.buf, pending_len);
  pending_len = 0;
  if (pending_is_data) {
    n_sent++;
    ring_tail = (uint8_t)((ring_tail + 1) & (RING_SIZE - 1));
  } else {
    ring[ring_tail].missed_before = 0;
  }
}

// ---------------------------------------------------------------------------------------------------------
// Sampler control

static void sampler_start() {
  uint16_t top = (uint16_t)((TIMER1_HZ + rate_hz / 2) / rate_hz - 1);
  cli();
  ring_head = 0;
  ring_tail = 0;
  conv_busy = 0;
  missed = 0;
  n_sent = 0;
  pending_len = 0;
  TCCR1A = 0;
  TCCR1B = 0;
  TCNT1 = 0;
  OCR1A = top;
  TIFR1 = _BV(OCF1A);
  TIMSK1 = _BV(OCIE1A);
  TCCR1B = _BV(WGM12) | _BV(CS11);  // CTC on OCR1A, clk/8
  streaming = 1;
  sei();
}

// Stops sampling, waits for a conversion in flight, then sends every sample taken (blocking).
static void sampler_stop() {
  cli();
  TCCR1B = 0;
  TIMSK1 = 0;
  sei();
  while (conv_busy) {
  }
  while (ring_tail != ring_head) service_stream();
  uint32_t m;
  cli();
  m = missed;
  missed = 0;
  sei();
  if (m) {  // periods missed after the last sample taken: still reported, never dropped
    out.begin();
    out.line.str_P(PSTR("W,OVERRUN,"));
    out.line.u32(m);
    out.send();
  }
  streaming = 0;
}

// ---------------------------------------------------------------------------------------------------------
// Commands

static void handle(Command *cmd) {
  if (proto_is(cmd, PSTR("PING"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("PING takes no argument"));
    out.text(PSTR("PONG daq " FW_VERSION));
  } else if (proto_is(cmd, PSTR("RATE"))) {
    if (!proto_args_ok(cmd, 1)) return out.err(PSTR("ARG"), PSTR("RATE needs 1 integer"));
    if (streaming) return out.err(PSTR("STATE"), PSTR("streaming"));
    int32_t hz = cmd->arg[0];
    if (hz < RATE_MIN_HZ || hz > RATE_MAX_HZ) return out.err(PSTR("RANGE"), PSTR("rate 100-2000 Hz"));
    rate_hz = (uint16_t)hz;
    out.word_u32(PSTR("OK RATE"), rate_hz);
  } else if (proto_is(cmd, PSTR("ZERO"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("ZERO takes no argument"));
    cli();
    step_count = 0;
    sei();
    out.text(PSTR("OK ZERO"));
  } else if (proto_is(cmd, PSTR("START"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("START takes no argument"));
    if (streaming) return out.err(PSTR("STATE"), PSTR("streaming"));
    out.word_u32(PSTR("OK START"), rate_hz);  // queued before the first data line
    sampler_start();
  } else if (proto_is(cmd, PSTR("STOP"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("STOP takes no argument"));
    uint32_t n = 0;
    if (streaming) {
      sampler_stop();
      n = n_sent;
    }
    out.word_u32(PSTR("OK STOP"), n);
  } else {
    out.err(PSTR("UNKNOWN"), PSTR("command"));
  }
}

static LineReader reader;

static void service_rx() {
  // A few bytes per pass, so that the stream keeps flowing while a command arrives.
  for (uint8_t i = 0; i < 16 && Serial.available() > 0; i++) {
    LineEvent ev = reader.feed((char)Serial.read());
    if (ev == LINE_NONE) continue;
    if (ev == LINE_TOOLONG) {
      out.err(PSTR("TOOLONG"), PSTR("line over 63 characters"));
    } else {
      Command cmd;
      if (!out.refused(proto_parse(reader.buf, reader.len, &cmd))) handle(&cmd);
    }
    reader.reset();
  }
}

void setup() {
  Serial.begin(500000);
  reader.reset();
  // ADC: AVcc reference, channel A0, enabled with its interrupt, clk/128 (125 kHz, 104 us per conversion).
  ADMUX = _BV(REFS0);
  ADCSRB = 0;
  DIDR0 = _BV(ADC0D);
  ADCSRA = _BV(ADEN) | _BV(ADIE) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);
  // STEP (D2/PE4) and DIR (D4/PG5) as inputs; INT4 on the rising edge.
  DDRE &= ~_BV(PE4);
  DDRG &= ~_BV(PG5);
  EICRB = (EICRB & ~(_BV(ISC41) | _BV(ISC40))) | _BV(ISC41) | _BV(ISC40);
  EIFR = _BV(INTF4);
  EIMSK |= _BV(INT4);
  out.text(PSTR("HELLO daq " FW_VERSION));
}

void loop() {
  service_rx();
  if (streaming) service_stream();
}
