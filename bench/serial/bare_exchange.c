/* The bare exchange: the serial benchmark's reference for a chain's poll cycle. It writes the
 * requests the gateway wrote, in the gateway's order, over the same PTY to the same simulator
 * (same baud, same wire-time emulation), and reads each reply until it is complete before the
 * next request: no scheduling, no parsing, no guard times, nothing but write(), poll() and
 * read(). What it achieves is the rate the line and the simulator allow for that traffic, so
 * bench/serial/run holds the gateway's rate against it, measured in the same run.
 *
 * Why not only the modelled ideal of analyse.py (request, echo and reply bytes over the baud plus
 * the turnaround): the model's errors go both ways. It knows nothing of what an exchange costs on
 * a PTY (the simulator's wake-ups, its 1 ms transmit chunks, the reader's own wake-ups), so it is
 * too fast where those weigh (Copley, IMS and Whedco at 115200); it charges a turnaround to
 * requests that get no reply (Centent's leading CR and unit selections, sent back to back), so it
 * is too slow there and ratios exceed 1 (IMS's and Whedco's at 9600 come out too slow as well).
 * The bare exchange pays what any program would on this line, and nothing of the gateway.
 *
 *   bare_exchange [--warmup S] [--timeout-ms MS] [--turn-us US] PTY BAUD SECONDS SCRIPT
 *
 * --turn-us US (default 0) spends US microseconds on the CPU between the end of each reply and
 * the next request, as a program doing its own work there would: not a reference, a diagnostic.
 * Run beside the plain bare exchange, it shows what a turn of that length costs on this host
 * (docs/performance.md, "A turn's cost on this host").
 *
 * SCRIPT (written by bench/serial/bare_script.py from the simulator's --wire-log of a gateway
 * run) has one exchange per line: "P|L BYTES HEX", HEX the request's bytes and BYTES how many
 * bytes the host reads back for it (the device's echo plus its reply, exactly as the simulator
 * logged them; 0: none, the next request follows at once). Taking each reply's length from the
 * capture treats every family alike: a local echo (IMS, Whedco) or a reply without a fixed
 * terminator needs no rule of its own. The P lines (the gateway's start-up, which puts the
 * simulated devices into the state the cycle expects) run once; the L lines (whole poll cycles)
 * then repeat until SECONDS have passed. Without L lines the run ends with the script. Lines
 * starting with '#' are comments.
 *
 * The tty is opened raw (cfmakeraw, CLOCAL | CREAD, no flow control) at BAUD, input and output
 * flushed, as the gateway opens it. A reply that is still incomplete after MS milliseconds
 * (default 100) plus twice the wire time of the exchange is counted as missing, the line is
 * drained until quiet and the next exchange follows: a missing reply never hangs the run. Bytes
 * read beyond a reply's expected length are counted (overlong) and dropped.
 *
 * Prints one line: "bare_exchange cycles C exchanges N seconds S per_s R missing M overlong O
 * mean_gap_us G", its own count on its own clock (bench/serial/run compares the simulator's logs
 * instead, exchange for exchange). The rate is taken over whole cycles where there are two cycle
 * starts after --warmup seconds (default 0), so that every request of the cycle weighs in it as
 * often as in the gateway's (a cycle can mix 4 ms and 190 ms exchanges): C cycles of the L lines,
 * N = C x their count, S seconds from the first cycle start to the last. Otherwise (C = 0) over
 * the N + 1 exchanges written after the warm-up, S seconds from the first write to the last. M and
 * O count the exchanges written after the warm-up; G is the mean time from the end of a reply
 * (its last byte read) to the next request's write, over those that had a reply.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

struct exchange {
  unsigned char* request;
  size_t request_size;
  size_t expect; /* bytes read back: echo plus reply */
};

struct script {
  struct exchange* items;
  size_t count;
  size_t prologue; /* the first `prologue` items run once, the rest repeat */
};

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

static int hex_value(int c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

static void load_script(const char* path, struct script* s) {
  FILE* f = fopen(path, "r");
  if (f == NULL) {
    fprintf(stderr, "bare_exchange: cannot open %s: %s\n", path, strerror(errno));
    exit(2);
  }
  size_t capacity = 0;
  char* line = NULL;
  size_t line_capacity = 0;
  int in_loop = 0;
  unsigned long number = 0;
  memset(s, 0, sizeof *s);
  while (getline(&line, &line_capacity, f) >= 0) {
    ++number;
    if (line[0] == '#' || line[0] == '\n' || line[0] == '\0') continue;
    char kind = 0;
    unsigned long expect = 0;
    int consumed = 0;
    if (sscanf(line, "%c %lu %n", &kind, &expect, &consumed) < 2 || (kind != 'P' && kind != 'L') ||
        (kind == 'P' && in_loop)) {
      fprintf(stderr, "bare_exchange: %s:%lu: expected \"P|L BYTES HEX\", P lines first\n", path,
              number);
      exit(2);
    }
    const char* hex = line + consumed;
    size_t digits = strspn(hex, "0123456789abcdefABCDEF");
    if (digits == 0 || digits % 2 != 0) {
      fprintf(stderr, "bare_exchange: %s:%lu: the request must be non-empty hex\n", path, number);
      exit(2);
    }
    if (s->count == capacity) {
      capacity = capacity ? 2 * capacity : 256;
      s->items = realloc(s->items, capacity * sizeof *s->items);
      if (s->items == NULL) exit(3);
    }
    struct exchange* x = &s->items[s->count++];
    x->request_size = digits / 2;
    x->request = malloc(x->request_size);
    if (x->request == NULL) exit(3);
    for (size_t i = 0; i < x->request_size; ++i) {
      x->request[i] = (unsigned char)(hex_value(hex[2 * i]) << 4 | hex_value(hex[2 * i + 1]));
    }
    x->expect = expect;
    if (kind == 'P') {
      s->prologue = s->count;
    } else {
      in_loop = 1;
    }
  }
  free(line);
  fclose(f);
  if (s->count == 0) {
    fprintf(stderr, "bare_exchange: %s has no exchanges\n", path);
    exit(2);
  }
}

static speed_t speed_of(long baud) {
  switch (baud) {
    case 1200:
      return B1200;
    case 2400:
      return B2400;
    case 4800:
      return B4800;
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    default:
      return 0;
  }
}

static int open_tty(const char* path, long baud) {
  const speed_t speed = speed_of(baud);
  if (speed == 0) {
    fprintf(stderr, "bare_exchange: unsupported baud %ld\n", baud);
    exit(2);
  }
  const int fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    fprintf(stderr, "bare_exchange: cannot open %s: %s\n", path, strerror(errno));
    exit(1);
  }
  struct termios tio;
  if (tcgetattr(fd, &tio) != 0) {
    perror("bare_exchange: tcgetattr");
    exit(1);
  }
  cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~(tcflag_t)(CRTSCTS | CSTOPB);
  tio.c_iflag &= ~(tcflag_t)(IXON | IXOFF | IXANY);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  cfsetispeed(&tio, speed);
  cfsetospeed(&tio, speed);
  if (tcsetattr(fd, TCSANOW, &tio) != 0) {
    perror("bare_exchange: tcsetattr");
    exit(1);
  }
  tcflush(fd, TCIOFLUSH);
  return fd;
}

/* Waits up to `deadline` (seconds, CLOCK_MONOTONIC) for `events` on fd; 0 on timeout. */
static int wait_for(int fd, short events, double deadline) {
  for (;;) {
    const double left = deadline - now_s();
    if (left <= 0) return 0;
    struct pollfd p = {fd, events, 0};
    const int ready = poll(&p, 1, (int)(left * 1000) + 1);
    if (ready > 0) return 1;
    if (ready < 0 && errno != EINTR) {
      perror("bare_exchange: poll");
      exit(1);
    }
  }
}

static void write_all(int fd, const unsigned char* bytes, size_t size, double deadline) {
  while (size > 0) {
    const ssize_t n = write(fd, bytes, size);
    if (n > 0) {
      bytes += n;
      size -= (size_t)n;
    } else if (n < 0 && errno != EAGAIN && errno != EINTR) {
      perror("bare_exchange: write");
      exit(1);
    } else if (!wait_for(fd, POLLOUT, deadline)) {
      fprintf(stderr, "bare_exchange: the tty accepts no more bytes\n");
      exit(1);
    }
  }
}

/* Reads and drops whatever arrives until the line has been quiet for `quiet_s`. */
static void drain_until_quiet(int fd, double quiet_s) {
  unsigned char buffer[512];
  while (wait_for(fd, POLLIN, now_s() + quiet_s)) {
    if (read(fd, buffer, sizeof buffer) <= 0 && errno != EAGAIN && errno != EINTR) break;
  }
  tcflush(fd, TCIFLUSH);
}

static void usage(void) {
  fprintf(stderr,
          "usage: bare_exchange [--warmup S] [--timeout-ms MS] [--turn-us US] PTY BAUD SECONDS "
          "SCRIPT\n");
  exit(2);
}

int main(int argc, char** argv) {
  double warmup = 0;
  double timeout_s = 0.1;
  double turn_s = 0;
  int arg = 1;
  while (arg < argc && strncmp(argv[arg], "--", 2) == 0) {
    if (strcmp(argv[arg], "--warmup") == 0 && arg + 1 < argc) {
      warmup = atof(argv[arg + 1]);
    } else if (strcmp(argv[arg], "--timeout-ms") == 0 && arg + 1 < argc) {
      timeout_s = atof(argv[arg + 1]) / 1000;
    } else if (strcmp(argv[arg], "--turn-us") == 0 && arg + 1 < argc) {
      turn_s = atof(argv[arg + 1]) / 1e6;
      if (turn_s < 0 || turn_s > 0.1) {
        fprintf(stderr, "bare_exchange: --turn-us takes 0 to 100000 microseconds\n");
        exit(2);
      }
    } else {
      usage();
    }
    arg += 2;
  }
  if (argc - arg != 4) usage();
  const char* tty = argv[arg];
  const long baud = atol(argv[arg + 1]);
  const double seconds = atof(argv[arg + 2]);
  struct script script;
  load_script(argv[arg + 3], &script);
  const int fd = open_tty(tty, baud);
  const double char_s = 10.0 / (double)baud; /* 8N1, as the benchmark's gateway runs */

  size_t largest = 0;
  for (size_t i = 0; i < script.count; ++i) {
    if (script.items[i].expect > largest) largest = script.items[i].expect;
  }
  const size_t buffer_size = largest + 4096;
  unsigned char* buffer = malloc(buffer_size);
  if (buffer == NULL) return 3;

  const size_t cycle = script.count - script.prologue;
  long cycles = 0, counted = 0, missing = 0, overlong = 0, gaps = 0;
  double gap_sum = 0;
  double first_write = -1, last_write = -1; /* writes after the warm-up */
  double first_cycle = -1, last_cycle = -1; /* cycle starts (writes) after the warm-up */
  double reply_end = -1;                    /* when the last byte of the previous reply was read */
  const double start = now_s();
  const double measure_from = start + warmup;
  const double stop = start + seconds;
  size_t next = 0;
  for (;;) {
    /* --turn-us: a program's own work between a reply and its next request, spent on the CPU
     * (a busy wait, not a sleep), so that its cost on this host can be told from the line's. */
    if (turn_s > 0 && reply_end >= 0) {
      while (now_s() < reply_end + turn_s) {
      }
    }
    const double written = now_s();
    if (written >= stop || next == script.count) break;
    const int cycle_start = next == script.prologue;
    const struct exchange* x = &script.items[next];
    next = next + 1 < script.count || cycle == 0 ? next + 1 : script.prologue;
    const double limit = written + timeout_s + 2 * char_s * (double)(x->request_size + x->expect);
    write_all(fd, x->request, x->request_size, limit);
    const int counting = written >= measure_from;
    if (counting && cycle_start) {
      if (first_cycle < 0) {
        first_cycle = written;
      } else {
        last_cycle = written;
        ++cycles;
      }
    }
    if (counting) {
      if (first_write < 0) first_write = written;
      last_write = written;
      ++counted;
      if (reply_end >= 0) {
        gap_sum += written - reply_end;
        ++gaps;
      }
    }
    reply_end = -1;
    size_t got = 0;
    int lost = 0;
    /* No reply can be there yet (the device's turnaround): wait first, then read. */
    while (got < x->expect) {
      if (!wait_for(fd, POLLIN, limit)) {
        lost = 1;
        break;
      }
      const ssize_t n = read(fd, buffer, buffer_size);
      if (n > 0) {
        got += (size_t)n;
      } else if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
        fprintf(stderr, "bare_exchange: read %s: %s\n", tty,
                n == 0 ? "end of file" : strerror(errno));
        return 1;
      }
    }
    const double done = now_s();
    if (lost) {
      if (counting) ++missing;
      drain_until_quiet(fd, 0.02);
    } else if (x->expect > 0) {
      reply_end = done;
      if (got > x->expect && counting) ++overlong;
    }
  }
  if (cycles == 0 && counted < 2) {
    fprintf(stderr, "bare_exchange: fewer than two exchanges after the %.1f s warm-up\n", warmup);
    return 1;
  }
  const double window = cycles ? last_cycle - first_cycle : last_write - first_write;
  const long exchanges = cycles ? cycles * (long)cycle : counted - 1;
  printf(
      "bare_exchange cycles %ld exchanges %ld seconds %.3f per_s %.1f missing %ld overlong %ld "
      "mean_gap_us %.1f\n",
      cycles, exchanges, window, (double)exchanges / window, missing, overlong,
      gaps ? gap_sum / (double)gaps * 1e6 : 0.0);
  return 0;
}
