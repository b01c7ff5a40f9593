/* tests/common/wire.c - see wire.h. */
#include "wire.h"

#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "proto.h"
#include "wait.h"

size_t st_wire_frame(uint8_t *out, const char *magic, unsigned version, unsigned op,
                     unsigned flags, uint32_t reqid, const void *body, uint32_t len,
                     uint32_t claimed_len)
{
    memcpy(out, magic, 4);
    out[4] = (uint8_t)version;
    out[5] = (uint8_t)op;
    stp_wr16(out + 6, (uint16_t)flags);
    stp_wr32(out + 8, reqid);
    stp_wr16(out + 12, 0);
    stp_wr16(out + 14, 0);
    stp_wr32(out + 16, claimed_len);
    stp_wr32(out + 20, 0);
    if (len)
        memcpy(out + ST_WIRE_HEADER, body, len);
    return ST_WIRE_HEADER + (size_t)len;
}

int st_wire_listen(int backlog, int *port)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t al = sizeof a;
    if (bind(fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(fd, backlog) != 0 ||
        getsockname(fd, (struct sockaddr *)&a, &al) != 0) {
        close(fd);
        return -1;
    }
    *port = ntohs(a.sin_port);
    return fd;
}

int st_wire_free_port(void)
{
    int port = -1, fd = st_wire_listen(1, &port);
    if (fd < 0)
        return -1;
    close(fd);
    return port;
}

int st_wire_send_all(int fd, const void *p, size_t n)
{
    const uint8_t *b = p;
    while (n) {
        ssize_t w = send(fd, b, n, MSG_NOSIGNAL);
        if (w <= 0)
            return -1;
        b += w;
        n -= (size_t)w;
    }
    return 0;
}

int st_wire_read_reply(int fd, st_wire_reply *r, int timeout_ms)
{
    uint8_t hdr[ST_WIRE_HEADER];
    size_t got = 0;
    int64_t end = st_now_ms() + timeout_ms;
    uint32_t need = ST_WIRE_HEADER;
    uint8_t *dst = hdr;
    for (int phase = 0; phase < 2; phase++) {
        while (got < need) {
            struct pollfd p = {fd, POLLIN, 0};
            int left = (int)(end - st_now_ms());
            if (left <= 0 || poll(&p, 1, left) <= 0)
                return -1;
            ssize_t n = recv(fd, dst + got, need - got, 0);
            if (n <= 0)
                return -1;
            got += (size_t)n;
        }
        if (phase == 0) {
            if (memcmp(hdr, "STX1", 4) != 0)
                return -1;
            r->op = hdr[5];
            r->flags = stp_rd16(hdr + 6);
            r->reqid = stp_rd32(hdr + 8);
            r->status = stp_rd16(hdr + 12);
            r->len = stp_rd32(hdr + 16);
            if (r->len > sizeof r->body)
                return -1;
            need = r->len;
            got = 0;
            dst = r->body;
        }
    }
    return 0;
}

int st_wire_peer_closed(int fd, int timeout_ms)
{
    if (!st_wait_readable(fd, timeout_ms))
        return 0;
    uint8_t b[256];
    return recv(fd, b, sizeof b, MSG_DONTWAIT) == 0;
}

size_t st_wire_sample_body(uint8_t *out, const char *name, uint32_t claimed_count,
                           const float *q7, uint32_t nq)
{
    size_t nl = strlen(name), o = 0;
    stp_wr16(out, (uint16_t)nl);
    memcpy(out + 2, name, nl);
    o = 2 + nl;
    out[o++] = 1;  /* traverse */
    out[o++] = 1;  /* bilinear */
    out[o++] = 0;
    out[o++] = 0;
    out[o++] = 0;  /* f32 */
    out[o++] = STP_SF_STATUS;
    out[o++] = 0;
    out[o++] = 0;
    memset(out + o, 0, 12);
    o += 12;
    stp_wr32(out + o, claimed_count);
    o += 4;
    for (uint32_t i = 0; i < nq; i++) {
        stp_wr32(out + o, (uint32_t)q7[i * 7]);
        for (int k = 1; k < 7; k++)
            stp_wr32(out + o + 4 * (size_t)k, stp_f2u(q7[i * 7 + k]));
        o += 28;
    }
    return o;
}

int st_wire_upload_begin(stp_buf *b, uint32_t reqid, const char *name, const char *hint,
                         const char *options, uint64_t total_size, uint32_t crc32c,
                         uint32_t flags)
{
    stp_upload_begin ub;
    memset(&ub, 0, sizeof ub);
    if (snprintf(ub.name, sizeof ub.name, "%s", name) >= (int)sizeof ub.name ||
        snprintf(ub.hint, sizeof ub.hint, "%s", hint ? hint : "") >= (int)sizeof ub.hint ||
        snprintf(ub.options, sizeof ub.options, "%s", options ? options : "") >=
            (int)sizeof ub.options)
        return -1;
    ub.total_size = total_size;
    ub.crc32c = crc32c;
    ub.flags = flags;
    return stp_enc_upload_begin(b, reqid, 0, &ub);
}
