/*
 * simavr_harness: runs a firmware ELF in simavr (Debian's libsimavr 1.6) for the firmware tests.
 *
 *   simavr_harness -m MCU [options] firmware.elf
 *
 *   -m MCU        atmega2560 or atmega328p (16 MHz; -f HZ to change)
 *   -d SECONDS    simulated duration (default: unlimited in pty mode, 1 s otherwise)
 *   -i FILE       timed UART input script: lines "<t_s> <text>"; <text> is sent at simulated time t_s,
 *                 with C escapes \n \r \t \\ \xHH (nothing is appended: end a command with \n)
 *   -p            UART on a pseudo-terminal: prints "PTY <path>" on stdout, then serves it until -d or SIGTERM
 *   -s FACTOR     pty mode pacing: at most FACTOR x real time (default 1; 0 = as fast as possible)
 *   -T            stdio mode: prefix every UART output line with the cycle count at its '\n'
 *   -a FILE       ADC waveform: lines "<t_s> <mV0> [<mV1> ...]" for ADC0 (and ADC1.. ADC7: one column each, as
 *                 many as the first line has), linear in between, held before/after; sampled at each
 *                 conversion start (ADC_IRQ_OUT_TRIGGER), every channel at once
 *   -A FILE       log of each conversion: "<cycle> <mV0> [<mV1> ...]" (and "# trigger <cycle>" when -t fires)
 *   -t PIN        the waveform's time 0 is the first rising edge of the first board's pin PIN (e.g. E4, the
 *                 Mega's STEP input); until then ADC0 reads the waveform's first value. For recordings whose
 *                 input depends on when a motion starts (firmware in the loop: tension computed from the
 *                 stepper's steps)
 *   -e FILE       input pin edges: lines "<t_s> <port><bit> <0|1>", e.g. "0.25 E4 1"
 *   -w LIST       output pins to log, e.g. D5,D6,D7
 *   -l FILE       pin log: "<cycle> <port><bit> <level>" for every change of a -w pin (initial levels at 0)
 *   -2 ELF        a second board (the whole rig in one process, in lockstep): its MCU is given by -M
 *                 (default atmega328p) and its UART is on a second pseudo-terminal (needs -p), announced as
 *                 "PTY2 <path>"; the options above (-a -e -w -i) apply to the first board only
 *   -c LIST       wires from the second board's output pins to the first board's input pins, e.g.
 *                 D5:E4,D6:G5 (Uno STEP D5 -> Mega D2, Uno DIR D6 -> Mega D4)
 *
 * In stdio mode the UART output goes to stdout and libsimavr's own chatter is moved to stderr.
 * vcc = avcc = aref = 5000 mV (simavr would assume 3300 mV). simavr 1.6 polls INT0/INT1 level triggers on
 * every cycle while such a pin is low, so the strict level trigger is switched off for every INTn.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <pty.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "avr_adc.h"
#include "avr_extint.h"
#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"

/* One simulated board: its MCU and its UART0 plumbing. */
typedef struct board {
  avr_t *avr;
  uint8_t *inq;          /* bytes waiting to be fed to UART0 */
  size_t inq_len, inq_pos, inq_cap;
  int xoff;              /* simavr's UART input FIFO is full */
  avr_irq_t *uart_in;
  int pty;               /* pseudo-terminal master, or -1 for stdio */
  uint8_t obuf[8192];    /* output for the pseudo-terminal, flushed every 100 us of simulated time */
  size_t olen;
  char linebuf[4096];
  size_t linelen;
} board_t;

static board_t boards[2];
static int nboards = 1;
static avr_t *avr;             /* the first board's MCU (waveform, edges, pin log, script) */
static FILE *out;              /* UART output in stdio mode */
static int timestamps;

static void die(const char *msg) {
  fprintf(stderr, "simavr_harness: %s\n", msg);
  exit(2);
}

static void *xrealloc(void *p, size_t n) {
  void *q = realloc(p, n);
  if (!q) die("out of memory");
  return q;
}

static avr_cycle_count_t sec_to_cycles(double t) {
  return (avr_cycle_count_t)llround(t * (double)avr->frequency);
}

/* ------------------------------------------------------------------------------------------------------ */
/* UART input queue, pumped into simavr while it is not signalling XOFF                                    */

static void inq_push(board_t *bd, const uint8_t *b, size_t n) {
  if (bd->inq_pos == bd->inq_len) bd->inq_pos = bd->inq_len = 0;
  if (bd->inq_len + n > bd->inq_cap) {
    bd->inq_cap = (bd->inq_len + n) * 2 + 256;
    bd->inq = xrealloc(bd->inq, bd->inq_cap);
  }
  memcpy(bd->inq + bd->inq_len, b, n);
  bd->inq_len += n;
}

static void uart_pump(board_t *bd) {
  while (!bd->xoff && bd->inq_pos < bd->inq_len) avr_raise_irq(bd->uart_in, bd->inq[bd->inq_pos++]);
}

static void on_xon(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq; (void)value;
  board_t *bd = param;
  bd->xoff = 0;
  uart_pump(bd);
}

static void on_xoff(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  board_t *bd = param;
  bd->xoff = value ? 1 : 0;
}

/* ------------------------------------------------------------------------------------------------------ */
/* UART output                                                                                             */

static volatile sig_atomic_t stop_requested;

/* Writes everything, waiting while a pseudo-terminal's buffer is full (the simulation then waits for its
 * reader, like back-pressure); gives up when asked to stop. */
static void write_all(int fd, const void *buf, size_t n) {
  const char *p = buf;
  while (n) {
    ssize_t w = write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN && !stop_requested) {
        struct timespec ts = {0, 200000};
        nanosleep(&ts, NULL);
        continue;
      }
      return;
    }
    p += w;
    n -= (size_t)w;
  }
}

static void on_uart_out(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  board_t *bd = param;
  uint8_t c = (uint8_t)value;
  if (bd->pty >= 0) {
    if (bd->olen == sizeof bd->obuf) {
      write_all(bd->pty, bd->obuf, bd->olen);
      bd->olen = 0;
    }
    bd->obuf[bd->olen++] = c;
    return;
  }
  if (!timestamps) {
    fputc(c, out);
    return;
  }
  if (bd->linelen < sizeof(bd->linebuf)) bd->linebuf[bd->linelen++] = (char)c;
  if (c == '\n') {
    fprintf(out, "%llu ", (unsigned long long)bd->avr->cycle);
    fwrite(bd->linebuf, 1, bd->linelen, out);
    bd->linelen = 0;
  }
}

/* ------------------------------------------------------------------------------------------------------ */
/* Timed input script                                                                                      */

typedef struct { avr_cycle_count_t at; uint8_t *bytes; size_t n; } script_ev_t;
static script_ev_t *script;
static size_t script_n, script_next;

static size_t unescape(const char *s, uint8_t *o) {
  size_t n = 0;
  while (*s && *s != '\n') {
    if (*s == '\\' && s[1]) {
      s++;
      switch (*s) {
        case 'n': o[n++] = '\n'; s++; break;
        case 'r': o[n++] = '\r'; s++; break;
        case 't': o[n++] = '\t'; s++; break;
        case '\\': o[n++] = '\\'; s++; break;
        case 'x': {
          char h[3] = {s[1], s[1] ? s[2] : 0, 0};
          o[n++] = (uint8_t)strtoul(h, NULL, 16);
          s += 3;
          break;
        }
        default: o[n++] = (uint8_t)*s++; break;
      }
    } else {
      o[n++] = (uint8_t)*s++;
    }
  }
  return n;
}

static void load_script(const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) die("cannot open the input script");
  char *line = NULL;
  size_t cap = 0;
  while (getline(&line, &cap, f) > 0) {
    char *end;
    double t = strtod(line, &end);
    if (end == line) continue; /* blank or comment line */
    if (*end == ' ') end++;
    script = xrealloc(script, (script_n + 1) * sizeof(*script));
    script[script_n].at = sec_to_cycles(t);
    script[script_n].bytes = xrealloc(NULL, strlen(end) + 1);
    script[script_n].n = unescape(end, script[script_n].bytes);
    script_n++;
  }
  free(line);
  fclose(f);
}

static avr_cycle_count_t script_timer(struct avr_t *a, avr_cycle_count_t when, void *param) {
  (void)a; (void)param;
  while (script_next < script_n && script[script_next].at <= when) {
    inq_push(&boards[0], script[script_next].bytes, script[script_next].n);
    script_next++;
  }
  uart_pump(&boards[0]);
  return script_next < script_n ? script[script_next].at : 0;
}

/* ------------------------------------------------------------------------------------------------------ */
/* ADC waveform                                                                                            */

#define WAVE_MAX_CH 8
static double *wave_t, *wave_mv;        /* wave_mv[i * wave_ch + c] */
static size_t wave_n, wave_ch;
static FILE *adc_log;
static avr_irq_t *adc_irq[WAVE_MAX_CH];
static int wave_triggered = 1;          /* 0 while -t waits for its edge */
static avr_cycle_count_t wave_origin;   /* cycle of the waveform's time 0 */

static void on_trigger(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq; (void)param;
  if (wave_triggered || !value) return;
  wave_triggered = 1;
  wave_origin = avr->cycle;
  if (adc_log) fprintf(adc_log, "# trigger %llu\n", (unsigned long long)wave_origin);
}

static void load_wave(const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) die("cannot open the ADC waveform");
  double t, v[WAVE_MAX_CH];
  size_t cap = 0;
  char buf[512];
  while (fgets(buf, sizeof buf, f)) {
    char *p = buf, *end;
    t = strtod(p, &end);
    if (end == p) continue;
    size_t nc = 0;
    for (p = end; nc < WAVE_MAX_CH; p = end) {
      v[nc] = strtod(p, &end);
      if (end == p) break;
      nc++;
    }
    if (!nc) continue;
    if (!wave_ch) wave_ch = nc;
    if (nc != wave_ch) die("every ADC waveform line needs the same number of channels");
    if (wave_n == cap) {
      cap = cap * 2 + 1024;
      wave_t = xrealloc(wave_t, cap * sizeof(double));
      wave_mv = xrealloc(wave_mv, cap * wave_ch * sizeof(double));
    }
    if (wave_n && t < wave_t[wave_n - 1]) die("ADC waveform times must not decrease");
    wave_t[wave_n] = t;
    for (size_t c = 0; c < wave_ch; c++) wave_mv[wave_n * wave_ch + c] = v[c];
    wave_n++;
  }
  fclose(f);
  if (!wave_n) die("empty ADC waveform");
}

static size_t wave_i;
static double wave_at(double t, size_t c) {
  const size_t k = wave_ch;
  if (t <= wave_t[0]) return wave_mv[c];
  if (t >= wave_t[wave_n - 1]) return wave_mv[(wave_n - 1) * k + c];
  if (wave_i >= wave_n - 1 || wave_t[wave_i] > t) wave_i = 0;
  while (wave_t[wave_i + 1] < t) wave_i++;
  double t0 = wave_t[wave_i], t1 = wave_t[wave_i + 1];
  double v0 = wave_mv[wave_i * k + c], v1 = wave_mv[(wave_i + 1) * k + c];
  if (t1 <= t0) return v1;
  return v0 + (v1 - v0) * (t - t0) / (t1 - t0);
}

static void on_adc_trigger(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq; (void)value; (void)param;
  if (adc_log) fprintf(adc_log, "%llu", (unsigned long long)avr->cycle);
  for (size_t c = 0; c < wave_ch; c++) {
    double mv = wave_triggered ? wave_at((double)(avr->cycle - wave_origin) / (double)avr->frequency, c)
                               : wave_mv[c];
    if (mv < 0) mv = 0;
    uint32_t imv = (uint32_t)llround(mv);
    if (adc_log) fprintf(adc_log, " %u", imv);
    avr_raise_irq(adc_irq[c], imv);
  }
  if (adc_log) fputc('\n', adc_log);
}

/* ------------------------------------------------------------------------------------------------------ */
/* Input pin edges and output pin log                                                                      */

typedef struct { avr_cycle_count_t at; avr_irq_t *irq; uint8_t level; } edge_t;
static edge_t *edges;
static size_t edge_n, edge_next;
static FILE *pin_log;

static void load_edges(const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) die("cannot open the pin edge file");
  char buf[256], port;
  int bit, level;
  double t;
  size_t cap = 0;
  while (fgets(buf, sizeof buf, f)) {
    if (sscanf(buf, "%lf %c%d %d", &t, &port, &bit, &level) != 4) continue;
    if (bit < 0 || bit > 7) die("pin bit must be 0-7");
    if (edge_n == cap) {
      cap = cap * 2 + 1024;
      edges = xrealloc(edges, cap * sizeof(edge_t));
    }
    edges[edge_n].at = sec_to_cycles(t);
    edges[edge_n].irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(port), bit);
    if (!edges[edge_n].irq) die("no such port");
    edges[edge_n].level = (uint8_t)(level != 0);
    if (edge_n && edges[edge_n].at < edges[edge_n - 1].at) die("edge times must not decrease");
    edge_n++;
  }
  fclose(f);
}

static avr_cycle_count_t edge_timer(struct avr_t *a, avr_cycle_count_t when, void *param) {
  (void)a; (void)param;
  while (edge_next < edge_n && edges[edge_next].at <= when) {
    avr_raise_irq(edges[edge_next].irq, edges[edge_next].level);
    edge_next++;
  }
  return edge_next < edge_n ? edges[edge_next].at : 0;
}

static void on_pin(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  const char *name = param;
  fprintf(pin_log, "%llu %s %u\n", (unsigned long long)avr->cycle, name, value ? 1u : 0u);
}

static void watch_pins(const char *list) {
  char *copy = strdup(list), *save = NULL;
  for (char *tok = strtok_r(copy, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
    if (strlen(tok) != 2 || tok[1] < '0' || tok[1] > '7') die("-w expects pins like D5,D6");
    avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(tok[0]), tok[1] - '0');
    if (!irq) die("no such port");
    avr_irq_register_notify(irq, on_pin, strdup(tok));
  }
  free(copy);
}

/* ------------------------------------------------------------------------------------------------------ */
/* Pseudo-terminal service and pacing                                                                      */

static double pace = 1.0;
static struct timespec wall0;
static void on_signal(int sig) { (void)sig; stop_requested = 1; }

#define HOST_LINK_BUFFER 128 /* bytes from the host the link holds before the board takes them (pty mode) */

static double wall_elapsed(void) {
  struct timespec now;
  clock_gettime(CLOCK_MONOTONIC, &now);
  return (double)(now.tv_sec - wall0.tv_sec) + 1e-9 * (double)(now.tv_nsec - wall0.tv_nsec);
}

static avr_cycle_count_t pty_timer(struct avr_t *a, avr_cycle_count_t when, void *param) {
  board_t *bd = param;
  uint8_t buf[256];
  ssize_t n;
  if (bd->olen) {
    write_all(bd->pty, bd->obuf, bd->olen);
    bd->olen = 0;
  }
  /* Read from the host only while little is queued, like a real USB-serial chip (its buffer of about 128
   * bytes, flow-controlled towards the host): a host's write of a long burst then lasts until the board has
   * nearly taken it in, as on the bench, instead of returning at once with the whole burst still to come. */
  while (bd->inq_len - bd->inq_pos < HOST_LINK_BUFFER && (n = read(bd->pty, buf, sizeof buf)) > 0)
    inq_push(bd, buf, (size_t)n);
  uart_pump(bd);
  if (pace > 0 && bd == &boards[0]) {
    double ahead = (double)when / (double)a->frequency / pace - wall_elapsed();
    if (ahead > 0.0005) {
      struct timespec ts = {(time_t)ahead, (long)((ahead - (double)(time_t)ahead) * 1e9)};
      nanosleep(&ts, NULL);
    }
  }
  return when + a->frequency / 10000; /* every 100 us of simulated time */
}

static void open_pty(board_t *bd, const char *label) {
  int slave;
  char name[256];
  if (openpty(&bd->pty, &slave, name, NULL, NULL) < 0) die("openpty failed");
  struct termios tio;
  tcgetattr(slave, &tio);
  cfmakeraw(&tio);
  tcsetattr(slave, TCSANOW, &tio);
  /* keep our slave descriptor open, so that the client may close and reopen the port */
  fcntl(bd->pty, F_SETFL, fcntl(bd->pty, F_GETFL) | O_NONBLOCK);
  fprintf(out, "%s %s\n", label, name); /* on the real stdout (fd 1 now carries libsimavr's chatter to stderr) */
  fflush(out);
}

/* ------------------------------------------------------------------------------------------------------ */

static void usage(void) {
  fprintf(stderr,
          "usage: simavr_harness -m atmega2560|atmega328p [-f HZ] [-d SECONDS] [-i SCRIPT | -p [-s FACTOR]] [-T]\n"
          "                      [-a WAVE [-t PIN]] [-A ADCLOG] [-e EDGES] [-w D5,D6 -l PINLOG]\n"
          "                      [-2 ELF2 [-M MCU2] [-c D5:E4,D6:G5]] firmware.elf\n");
  exit(2);
}

/* Creates a board running `elf` on `mcu` with its UART0 wired to the harness. */
static void board_init(board_t *bd, const char *mcu, const char *elf, double freq) {
  elf_firmware_t fw;
  memset(&fw, 0, sizeof fw);
  if (elf_read_firmware(elf, &fw) != 0) die("cannot read the ELF file");
  bd->avr = avr_make_mcu_by_name(mcu);
  if (!bd->avr) die("unknown MCU");
  avr_t *a = bd->avr;
  avr_init(a);
  a->log = LOG_ERROR;
  avr_load_firmware(a, &fw);
  a->frequency = (uint32_t)freq;
  a->vcc = a->avcc = a->aref = 5000;
  for (int n = 0; n < EXTINT_COUNT; n++) avr_extint_set_strict_lvl_trig(a, (uint8_t)n, 0);
  uint32_t flags = 0; /* no stdio echo, no usleep on polling */
  avr_ioctl(a, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
  bd->pty = -1;
  bd->uart_in = avr_io_getirq(a, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
  avr_irq_register_notify(avr_io_getirq(a, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), on_uart_out, bd);
  avr_irq_register_notify(avr_io_getirq(a, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), on_xon, bd);
  avr_irq_register_notify(avr_io_getirq(a, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), on_xoff, bd);
}

/* Wires output pins of board 1 to input pins of board 0: "D5:E4,D6:G5". */
static void connect_pins(const char *list) {
  char *copy = strdup(list), *save = NULL;
  for (char *tok = strtok_r(copy, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
    if (strlen(tok) != 5 || tok[2] != ':' || tok[1] < '0' || tok[1] > '7' || tok[4] < '0' || tok[4] > '7')
      die("-c expects wires like D5:E4,D6:G5");
    avr_irq_t *src = avr_io_getirq(boards[1].avr, AVR_IOCTL_IOPORT_GETIRQ(tok[0]), tok[1] - '0');
    avr_irq_t *dst = avr_io_getirq(boards[0].avr, AVR_IOCTL_IOPORT_GETIRQ(tok[3]), tok[4] - '0');
    if (!src || !dst) die("no such port");
    avr_connect_irq(src, dst);
  }
  free(copy);
}

int main(int argc, char **argv) {
  const char *mcu = NULL, *script_path = NULL, *wave_path = NULL, *adc_log_path = NULL;
  const char *edge_path = NULL, *watch = NULL, *pin_log_path = NULL, *trigger = NULL;
  const char *elf2 = NULL, *mcu2 = "atmega328p", *wires = NULL;
  double duration = -1, freq = 16e6;
  int use_pty = 0, opt;
  while ((opt = getopt(argc, argv, "m:f:d:i:ps:Ta:A:t:e:w:l:2:M:c:")) != -1) {
    switch (opt) {
      case 'm': mcu = optarg; break;
      case 'f': freq = atof(optarg); break;
      case 'd': duration = atof(optarg); break;
      case 'i': script_path = optarg; break;
      case 'p': use_pty = 1; break;
      case 's': pace = atof(optarg); break;
      case 'T': timestamps = 1; break;
      case 'a': wave_path = optarg; break;
      case 'A': adc_log_path = optarg; break;
      case 't': trigger = optarg; break;
      case 'e': edge_path = optarg; break;
      case 'w': watch = optarg; break;
      case 'l': pin_log_path = optarg; break;
      case '2': elf2 = optarg; break;
      case 'M': mcu2 = optarg; break;
      case 'c': wires = optarg; break;
      default: usage();
    }
  }
  if (!mcu || optind != argc - 1) usage();
  if (watch && !pin_log_path) die("-w needs -l");
  if (trigger && !wave_path) die("-t needs -a");
  if (elf2 && !use_pty) die("-2 needs -p (the second board's UART is on a pseudo-terminal)");
  if (wires && !elf2) die("-c needs -2");
  if (duration < 0 && !use_pty) duration = 1.0;

  /* libsimavr prints to stdout (UART configuration); keep stdout for the UART bytes only */
  int data_fd = dup(STDOUT_FILENO);
  dup2(STDERR_FILENO, STDOUT_FILENO);
  out = fdopen(data_fd, "w");
  if (!out) die("cannot reopen stdout");
  setvbuf(out, NULL, _IOFBF, 1 << 16);

  board_init(&boards[0], mcu, argv[optind], freq);
  avr = boards[0].avr;
  if (elf2) {
    board_init(&boards[1], mcu2, elf2, freq);
    nboards = 2;
    if (wires) connect_pins(wires);
  }

  if (wave_path) {
    load_wave(wave_path);
    for (size_t c = 0; c < wave_ch; c++) adc_irq[c] = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0 + c);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_OUT_TRIGGER), on_adc_trigger, NULL);
    if (adc_log_path && !(adc_log = fopen(adc_log_path, "w"))) die("cannot write the ADC log");
    if (trigger) {
      if (strlen(trigger) != 2 || trigger[1] < '0' || trigger[1] > '7') die("-t expects a pin like E4");
      avr_irq_t *irq = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(trigger[0]), trigger[1] - '0');
      if (!irq) die("no such port");
      avr_irq_register_notify(irq, on_trigger, NULL);
      wave_triggered = 0;
    }
  }
  if (edge_path) {
    load_edges(edge_path);
    if (edge_n) avr_cycle_timer_register(avr, edges[0].at ? edges[0].at : 1, edge_timer, NULL);
  }
  if (watch) {
    if (!(pin_log = fopen(pin_log_path, "w"))) die("cannot write the pin log");
    watch_pins(watch);
  }
  if (script_path) {
    load_script(script_path);
    if (script_n) avr_cycle_timer_register(avr, script[0].at ? script[0].at : 1, script_timer, NULL);
  }
  signal(SIGTERM, on_signal);
  signal(SIGINT, on_signal);
  signal(SIGPIPE, SIG_IGN);
  if (use_pty) {
    for (int b = 0; b < nboards; b++) {
      open_pty(&boards[b], b == 0 ? "PTY" : "PTY2");
      avr_cycle_timer_register(boards[b].avr, boards[b].avr->frequency / 10000, pty_timer, &boards[b]);
    }
    clock_gettime(CLOCK_MONOTONIC, &wall0);
  }

  avr_cycle_count_t end = duration >= 0 ? sec_to_cycles(duration) : (avr_cycle_count_t)-1;
  int state = cpu_Running;
  while (!stop_requested && avr->cycle < end) {
    /* two boards run in lockstep: always advance the one that is behind */
    avr_t *a = (nboards == 2 && boards[1].avr->cycle < avr->cycle) ? boards[1].avr : avr;
    state = avr_run(a);
    if (state == cpu_Done || state == cpu_Crashed) break;
  }
  if (timestamps && boards[0].linelen) {
    fprintf(out, "%llu ", (unsigned long long)avr->cycle);
    fwrite(boards[0].linebuf, 1, boards[0].linelen, out);
  }
  fflush(out);
  if (adc_log) fclose(adc_log);
  if (pin_log) fclose(pin_log);
  if (state == cpu_Crashed) {
    fprintf(stderr, "simavr_harness: a firmware crashed at cycle %llu\n", (unsigned long long)avr->cycle);
    return 3;
  }
  return 0;
}
