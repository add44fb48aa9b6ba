/* The tests' and the benchmark's WebSocket client (see ws_client.h). */
#include "ws_client.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

int km_live_ws_connect(const char *host, int port, const char *token, double timeout_s) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  if (timeout_s > 0) {
    struct timeval tv;
    tv.tv_sec = (time_t)timeout_s;
    tv.tv_usec = (suseconds_t)((timeout_s - (double)tv.tv_sec) * 1e6);
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }
  struct sockaddr_in a;
  memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)port);
  char req[512];
  int rn = snprintf(req, sizeof req,
                    "GET /ws%s%s HTTP/1.1\r\nHost: %s\r\nUpgrade: websocket\r\n"
                    "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                    "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: kinemesh\r\n\r\n",
                    token && *token ? "?token=" : "", token && *token ? token : "", host);
  if (inet_pton(AF_INET, host, &a.sin_addr) != 1 || rn <= 0 || (size_t)rn >= sizeof req ||
      connect(fd, (struct sockaddr *)&a, sizeof a) || send(fd, req, (size_t)rn, 0) != (ssize_t)rn) {
    close(fd);
    return -1;
  }
  char resp[2048];
  size_t n = 0;
  /* byte by byte so that no frame data is taken with the response */
  while (n + 1 < sizeof resp && recv(fd, resp + n, 1, 0) == 1) {
    ++n;
    if (n >= 4 && !memcmp(resp + n - 4, "\r\n\r\n", 4)) break;
  }
  resp[n] = 0;
  if (!strstr(resp, " 101 ")) {
    close(fd);
    return -1;
  }
  return fd;
}

static bool recv_full(int fd, unsigned char *b, size_t n) {
  while (n) {
    ssize_t r = recv(fd, b, n, 0);
    if (r <= 0) return false;
    b += r;
    n -= (size_t)r;
  }
  return true;
}

#define WS_MAX_MESSAGE ((uint64_t)64 << 20)

bool km_live_ws_read(int fd, unsigned char **msg, size_t *cap, size_t *len) {
  *len = 0;
  for (;;) {
    unsigned char h[10];
    if (!recv_full(fd, h, 2)) return false;
    uint64_t n = h[1] & 127;
    if (n == 126) {
      if (!recv_full(fd, h + 2, 2)) return false;
      n = ((uint64_t)h[2] << 8) | h[3];
    } else if (n == 127) {
      if (!recv_full(fd, h + 2, 8)) return false;
      n = 0;
      for (int k = 0; k < 8; ++k)
        n = (n << 8) | h[2 + k];
    }
    if (n > WS_MAX_MESSAGE || *len + n > WS_MAX_MESSAGE) return false;
    size_t need = *len + (size_t)n + 1;
    if (need > *cap) {
      size_t c = *cap ? *cap : 4096;
      while (c < need)
        c *= 2;
      unsigned char *b = realloc(*msg, c);
      if (!b) return false;
      *msg = b;
      *cap = c;
    }
    if (!recv_full(fd, *msg + *len, (size_t)n)) return false;
    int op = h[0] & 15;
    if (op == 8) return false;
    if (op == 9 || op == 10) continue; /* ping / pong, also between fragments */
    *len += (size_t)n;
    if (h[0] & 128) return true;
  }
}
