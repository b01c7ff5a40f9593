/* tests/common/wire.h - raw protocol frames on a socket, for tests that must send what
 * libseamtex never would (bad magic, lying lengths, truncated headers, unread pipelines) and
 * for benchmarks that talk to a socket directly.
 *
 * Owns: writing a request frame byte by byte (any magic, version, flags, claimed length),
 * sending a buffer whole, reading one reply frame with a deadline, telling a closed peer, a
 * SAMPLE body (traverse, bilinear, f32 with statuses) and an UPLOAD_BEGIN frame. Does not own: the protocol's encoders
 * (protocol/proto.h) or connections (daemon_fixture.h connects, daemon_client.h speaks
 * through libseamtex).
 */
#ifndef ST_WIRE_H
#define ST_WIRE_H

#include <stddef.h>
#include <stdint.h>

#include "proto.h"

#define ST_WIRE_HEADER 24

/* Writes a frame header (magic, version, opcode, flags, reqid, claimed_len as the body
 * length) and the len bytes of body into out (ST_WIRE_HEADER + len bytes); returns the frame
 * size. claimed_len may differ from len: that is what the malformed-frame tests send. */
size_t st_wire_frame(uint8_t *out, const char *magic, unsigned version, unsigned op,
                     unsigned flags, uint32_t reqid, const void *body, uint32_t len,
                     uint32_t claimed_len);

/* A TCP socket on 127.0.0.1, bound to a free port (written to *port) and listening with the
 * given backlog; the caller accepts on it, or never does (a peer that connects and gets no
 * answer). fd, or -1. */
int st_wire_listen(int backlog, int *port);
/* A loopback TCP port that was free a moment ago (bound, then closed: nothing listens on it
 * until someone binds it again), or -1. */
int st_wire_free_port(void);

/* Sends n bytes whole (blocking, no SIGPIPE). 0, or -1 when the socket fails. */
int st_wire_send_all(int fd, const void *p, size_t n);

typedef struct st_wire_reply {
    unsigned op, flags, status;
    uint32_t reqid, len;
    uint8_t  body[4096];
} st_wire_reply;

/* Reads one reply frame (magic STX1, body of at most 4096 bytes). 0, or -1 on timeout, close,
 * bad magic or a longer body. */
int st_wire_read_reply(int fd, st_wire_reply *r, int timeout_ms);

/* 1 when the peer closed the socket within timeout_ms (nothing more to read). */
int st_wire_peer_closed(int fd, int timeout_ms);

/* SAMPLE body for set `name`: traverse, bilinear, f32 values plus statuses, the
 * claimed_count in the count field and nq queries of 7 floats (face, u, v, dudx, dvdx, dudy,
 * dvdy) from q7. out must hold 34 + strlen(name) + 28 * nq bytes. Returns the body size. */
size_t st_wire_sample_body(uint8_t *out, const char *name, uint32_t claimed_count,
                           const float *q7, uint32_t nq);

/* Appends an UPLOAD_BEGIN frame to b (protocol/proto.h's encoder): set `name`, format `hint`
 * and import `options` (NULL: none), total_size, crc32c and flags (STP_UF_*). 0, or the
 * encoder's error (a name, hint or options too long). */
int st_wire_upload_begin(stp_buf *b, uint32_t reqid, const char *name, const char *hint,
                         const char *options, uint64_t total_size, uint32_t crc32c,
                         uint32_t flags);

#endif
