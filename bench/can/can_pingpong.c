/* The raw request/response ceiling of a CAN interface: one thread answers every 0x601 frame
 * with a 0x581 frame, the other sends a request and waits for its answer before the next, with
 * blocking reads and writes on raw sockets and nothing else. The CAN benchmark compares
 * fieldgate's SDO polling against this rate measured in the same run.
 *
 *   can_pingpong IFACE SECONDS     prints "pingpong_round_trips_per_s RATE"
 */
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

enum { kRequestId = 0x601, kResponseId = 0x581 };

static int open_socket(const char* ifname, canid_t receive_id) {
  const int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) {
    perror("socket(PF_CAN)");
    exit(1);
  }
  struct can_filter filter = {receive_id, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG};
  setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &filter, sizeof filter);
  struct sockaddr_can addr;
  memset(&addr, 0, sizeof addr);
  addr.can_family = AF_CAN;
  addr.can_ifindex = (int)if_nametoindex(ifname);
  if (addr.can_ifindex == 0 || bind(fd, (struct sockaddr*)&addr, sizeof addr) < 0) {
    fprintf(stderr, "can_pingpong: cannot bind to %s: %s\n", ifname, strerror(errno));
    exit(1);
  }
  return fd;
}

static void* responder(void* arg) {
  const int fd = *(const int*)arg;
  struct can_frame frame;
  for (;;) {
    if (read(fd, &frame, sizeof frame) != (ssize_t)sizeof frame) break;
    frame.can_id = kResponseId;
    frame.data[0] = 0x43;
    if (write(fd, &frame, sizeof frame) != (ssize_t)sizeof frame) break;
  }
  return NULL;
}

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + (double)ts.tv_nsec / 1e9;
}

int main(int argc, char** argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: can_pingpong IFACE SECONDS\n");
    return 2;
  }
  const double seconds = atof(argv[2]);
  int server = open_socket(argv[1], kRequestId);
  const int client = open_socket(argv[1], kResponseId);
  pthread_t thread;
  pthread_create(&thread, NULL, responder, &server);

  struct can_frame request;
  memset(&request, 0, sizeof request);
  request.can_id = kRequestId;
  request.len = 8;
  request.data[0] = 0x40;
  long round_trips = 0;
  const double start = now_s();
  double elapsed = 0;
  while (elapsed < seconds) {
    struct can_frame response;
    if (write(client, &request, sizeof request) != (ssize_t)sizeof request ||
        read(client, &response, sizeof response) != (ssize_t)sizeof response) {
      perror("can_pingpong");
      return 1;
    }
    ++round_trips;
    elapsed = now_s() - start;
  }
  printf("pingpong_round_trips_per_s %.1f\n", (double)round_trips / elapsed);
  return 0;
}
