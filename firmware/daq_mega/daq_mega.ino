// DAQ board: Arduino Mega 2560. Samples the load-cell amplifiers on A0..A3 (RIG_CHANNELS of them, from the rig
// config) and counts each stepper driver's STEP pulses (with DIR; RIG_AXES of them), streaming both on one
// clock. Protocol: firmware/PROTOCOL.md (RIG_DAQ_BAUD: 500000 baud for the paper's rig, 8N1).
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
// Several channels: the timer ISR starts channel 0 and takes every axis's step count at the same instant; the
// ADC-complete ISR starts the next channel (one 104 us conversion each) and stores the sample after the last.
//
// Pins: A0..A3 = amplifier outputs (via the 150 ohm shunts). Axis 0: D2 = STEP (INT4, rising edge), D4 = DIR
// (HIGH = pull); axis 1: D3 (INT5) / D5; axis 2: D19 (INT2) / D23; axis 3: D18 (INT3) / D25.

#include <avr/interrupt.h>
#include <avr/io.h>

#include "proto.h"
#include "reply.h"
#include "rig_config.h"

// The version reported in HELLO and PONG: the protocol version, then "+" and the rig config's hash.
#define FW_VERSION "2.3.0"
#define FW_ID FW_VERSION "+" RIG_HASH

#define CHANNELS RIG_CHANNELS
#define AXES RIG_AXES
static const uint16_t RATE_MIN_HZ = RIG_DAQ_RATE_MIN_HZ;
static const uint16_t RATE_MAX_HZ = RIG_DAQ_RATE_MAX_HZ;
static const uint16_t RATE_DEFAULT_HZ = RIG_DAQ_RATE_DEFAULT_HZ;
static const uint32_t TIMER1_HZ = 2000000UL;  // F_CPU / 8
static const uint16_t SAMPLE_LEAD_TICKS = 32;   // conversion start 16 us after the compare match

// ---------------------------------------------------------------------------------------------------------
// Sampler state (shared with the ISRs)

struct Sample {
  uint32_t t_us;
  int32_t steps[AXES];
  uint16_t adc[CHANNELS];
  uint32_t missed_before;  // sample periods missed just before this sample (0 normally)
};

#define RING_SIZE 64  // power of two; 64 samples = 32 ms of slack at 2 kHz
static volatile Sample ring[RING_SIZE];
// The ring is the DAQ's one large table: refuse a config whose ring leaves less than half the RAM.
static_assert(sizeof(ring) <= (RAMEND + 1 - RAMSTART) / 2, "rig config: the sample ring does not fit the Mega's RAM");
// Every channel converted within the shortest sample period (13 ADC clocks of 8 us each, plus the lead).
static_assert(CHANNELS * 104L + 16 < 1000000L / RIG_DAQ_RATE_MAX_HZ, "rig config: too many channels for the rate");
static volatile uint8_t ring_head;     // next slot the ADC ISR fills (written only by ISRs)
static volatile uint8_t ring_tail;     // next slot the main loop sends (written only by the main loop)
static volatile uint8_t conv_busy;     // a conversion started by the timer ISR is in progress
static volatile uint32_t missed;       // periods missed since the last sample taken
static volatile int32_t step_count[AXES];  // STEP pulses since ZERO, + for pulls
static volatile uint8_t conv_channel;  // the channel being converted

static uint8_t streaming;
static uint16_t rate_hz = RATE_DEFAULT_HZ;
static uint32_t n_sent;                // data lines sent since START (= next seq)

// Axis 0: STEP on D2 = PE4 = INT4 (rising edge); DIR on D4 = PG5, sampled on each pulse.
ISR(INT4_vect) {
  if (PING & _BV(PG5)) step_count[0]++;
  else step_count[0]--;
}
#if AXES > 1
// Axis 1: STEP D3 = PE5 = INT5, DIR D5 = PE3.
ISR(INT5_vect) {
  if (PINE & _BV(PE3)) step_count[1]++;
  else step_count[1]--;
}
#endif
#if AXES > 2
// Axis 2: STEP D19 = PD2 = INT2, DIR D23 = PA1.
ISR(INT2_vect) {
  if (PINA & _BV(PA1)) step_count[2]++;
  else step_count[2]--;
}
#endif
#if AXES > 3
// Axis 3: STEP D18 = PD3 = INT3, DIR D25 = PA3.
ISR(INT3_vect) {
  if (PINA & _BV(PA3)) step_count[3]++;
  else step_count[3]--;
}
#endif

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
  for (uint8_t a = 0; a < AXES; a++) s.steps[a] = step_count[a];
  s.t_us = micros();
  s.missed_before = missed;
  missed = 0;
  conv_busy = 1;
}

ISR(ADC_vect) {
  uint8_t head = ring_head;
#if CHANNELS > 1
  uint8_t ch = conv_channel;
  ring[head].adc[ch] = ADC;
  if (++ch < CHANNELS) {  // the next channel at once (A0..A3 are MUX 0..3 with MUX5 = 0)
    conv_channel = ch;
    ADMUX = (uint8_t)(_BV(REFS0) | ch);
    ADCSRA |= _BV(ADSC);
    return;
  }
  conv_channel = 0;
  ADMUX = _BV(REFS0);
#else
  ring[head].adc[0] = ADC;
#endif
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
      for (uint8_t c = 0; c < CHANNELS; c++) {
        pending.put(',');
        pending.u32(s.adc[c]);
      }
      for (uint8_t a = 0; a < AXES; a++) {
        pending.put(',');
        pending.i32(s.steps[a]);
      }
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
  conv_channel = 0;
  ADMUX = _BV(REFS0);
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
    out.text(PSTR("PONG daq " FW_ID));
  } else if (proto_is(cmd, PSTR("RATE"))) {
    if (!proto_args_ok(cmd, 1)) return out.err(PSTR("ARG"), PSTR("RATE needs 1 integer"));
    if (streaming) return out.err(PSTR("STATE"), PSTR("streaming"));
    int32_t hz = cmd->arg[0];
    if (hz < RATE_MIN_HZ || hz > RATE_MAX_HZ) {
      out.begin();
      out.line.str_P(PSTR("ERR RANGE rate "));
      out.line.u32(RATE_MIN_HZ);
      out.line.put('-');
      out.line.u32(RATE_MAX_HZ);
      out.line.str_P(PSTR(" Hz"));
      return out.send();
    }
    rate_hz = (uint16_t)hz;
    out.word_u32(PSTR("OK RATE"), rate_hz);
  } else if (proto_is(cmd, PSTR("ZERO"))) {
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("ZERO takes no argument"));
    cli();
    for (uint8_t a = 0; a < AXES; a++) step_count[a] = 0;
    sei();
    out.text(PSTR("OK ZERO"));
  } else if (proto_is(cmd, PSTR("CONFIG"))) {
    // CONFIG -> OK CONFIG <channels> <axes> <rate_min_hz> <rate_max_hz>
    if (!proto_args_ok(cmd, 0)) return out.err(PSTR("ARG"), PSTR("CONFIG takes no argument"));
    out.begin();
    out.line.str_P(PSTR("OK CONFIG "));
    out.line.u32(CHANNELS);
    out.line.put(' ');
    out.line.u32(AXES);
    out.line.put(' ');
    out.line.u32(RATE_MIN_HZ);
    out.line.put(' ');
    out.line.u32(RATE_MAX_HZ);
    out.send();
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
  Serial.begin(RIG_DAQ_BAUD);
  reader.reset();
  // ADC: AVcc reference, channel A0, enabled with its interrupt, clk/128 (125 kHz, 104 us per conversion).
  ADMUX = _BV(REFS0);
  ADCSRB = 0;
  DIDR0 = (uint8_t)((1 << CHANNELS) - 1);  // digital inputs off on A0..A(CHANNELS-1)
  ADCSRA = _BV(ADEN) | _BV(ADIE) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);
  // STEP (D2/PE4) and DIR (D4/PG5) as inputs; INT4 on the rising edge.
  DDRE &= ~_BV(PE4);
  DDRG &= ~_BV(PG5);
  EICRB = (EICRB & ~(_BV(ISC41) | _BV(ISC40))) | _BV(ISC41) | _BV(ISC40);
  EIFR = _BV(INTF4);
  EIMSK |= _BV(INT4);
#if AXES > 1
  DDRE &= (uint8_t)~(_BV(PE5) | _BV(PE3));
  EICRB |= _BV(ISC51) | _BV(ISC50);
  EIFR = _BV(INTF5);
  EIMSK |= _BV(INT5);
#endif
#if AXES > 2
  DDRD &= (uint8_t)~_BV(PD2);
  DDRA &= (uint8_t)~_BV(PA1);
  EICRA |= _BV(ISC21) | _BV(ISC20);
  EIFR = _BV(INTF2);
  EIMSK |= _BV(INT2);
#endif
#if AXES > 3
  DDRD &= (uint8_t)~_BV(PD3);
  DDRA &= (uint8_t)~_BV(PA3);
  EICRA |= _BV(ISC31) | _BV(ISC30);
  EIFR = _BV(INTF3);
  EIMSK |= _BV(INT3);
#endif
  out.text(PSTR("HELLO daq " FW_ID));
}

void loop() {
  service_rx();
  if (streaming) service_stream();
}
