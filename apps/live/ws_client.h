/* A minimal WebSocket client on a plain socket: what a browser page receives from the live
 * server, for the tests (tests/test_live.c) and the latency benchmark (bench/bench_live.c).
 * libwebsockets 4.1's client parses received payload byte by byte (about 150 MB/s here), which
 * would make a measuring client, not the server, the bottleneck for 700 KB frames; this one
 * reads whole frames with large recv()s. It speaks just enough RFC 6455 for the kinemesh
 * server: one fixed handshake, unmasked server frames, no extensions. */
#ifndef KM_LIVE_WS_CLIENT_H
#define KM_LIVE_WS_CLIENT_H

#include <stdbool.h>
#include <stddef.h>

/* Connects to ws://host:port/ws?token=TOKEN (token NULL or "": none; km_live_token gives the
 * server's) with subprotocol "kinemesh" and completes the handshake.
 * timeout_s > 0 bounds every later receive (a server that stops sending makes
 * km_live_ws_read return false instead of hanging); 0 waits for ever. Returns the socket
 * (close it with close()), or -1 when the connection or the handshake failed. */
int km_live_ws_connect(const char *host, int port, const char *token, double timeout_s);

/* The next whole data message (text or binary; fragments joined, ping/pong skipped) into
 * *msg, a malloc'ed buffer of *cap bytes that is grown as needed and may be reused across
 * calls (start with *msg = NULL, *cap = 0; the caller frees *msg). *len is the message's
 * length. Returns false on a close frame, a receive error or timeout, or a message over
 * 64 MiB. */
bool km_live_ws_read(int fd, unsigned char **msg, size_t *cap, size_t *len);

#endif
