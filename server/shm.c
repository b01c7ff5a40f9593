/* server/shm.c - shared-memory sampling for clients on a Unix connection (shm.h; PROTOCOL.md
 * 4.12).
 *
 * A client on the daemon's host creates a memfd, seals it against shrinking and growing,
 * maps it, and hands it over with SHM_ATTACH (the descriptor as SCM_RIGHTS ancillary data on
 * the frame's bytes). From then on a SAMPLE / SAMPLE_DIR with flag SHM carries three offsets
 * instead of its queries; shm_sample.c samples it in place (queries copied out in small
 * chunks, each read once, the reply written straight into the region) and answers with a
 * 16-byte frame saying where the reply body is and how long. Frames still carry ids, order
 * and errors, so pipelining and every status work as on the socket path.
 *
 * Every check on a descriptor is made before it is mapped (memfd: F_GET_SEALS works; seals
 * SHRINK and GROW present, WRITE absent; size equal to the announced one and within shm-max;
 * not hugetlbfs, whose faults can raise SIGBUS when the pool runs dry). With SHRINK and GROW
 * sealed the file's size cannot change, so no access inside the mapping can fault past its
 * end; offsets are checked with stp_shm_range_ok (no addition that could wrap).
 */
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/statfs.h>
#include <unistd.h>

#include "io.h"
#include "server.h"
#include "shm.h"

#define HUGETLBFS_MAGIC_ 0x958458f6   /* linux/magic.h; hugetlbfs faults may SIGBUS */

/* ---- descriptors ----------------------------------------------------------------------------- */

static sts_shm_conn *conn_shm(sts_conn *c)
{
    if (!c->shm) {
        c->shm = calloc(1, sizeof *c->shm);
    }
    return c->shm;
}

static void keep_fd(sts_server *srv, sts_conn *c, int fd)
{
    sts_shm_conn *s = conn_shm(c);
    if (!s || s->nfds >= STS_SHM_MAX_FDS) {
        close(fd);
        STS_STAT_ADD(srv, shm_fds_dropped, 1);
        return;
    }
    s->fds[s->nfds++] = fd;
}

ssize_t sts_shm_recv(sts_server *srv, sts_conn *c, struct iovec *iov, int niov)
{
    union {
        struct cmsghdr h;
        char b[CMSG_SPACE(sizeof(int) * 8)];
    } ctl;
    struct msghdr m;
    memset(&m, 0, sizeof m);
    m.msg_iov = iov;
    m.msg_iovlen = (size_t)niov;
    m.msg_control = ctl.b;
    m.msg_controllen = sizeof ctl.b;
    ssize_t r = recvmsg(c->fd, &m, MSG_DONTWAIT | MSG_CMSG_CLOEXEC);
    if (r < 0)
        return r;
    for (struct cmsghdr *h = CMSG_FIRSTHDR(&m); h; h = CMSG_NXTHDR(&m, h)) {
        if (h->cmsg_level != SOL_SOCKET || h->cmsg_type != SCM_RIGHTS)
            continue;
        size_t n = (h->cmsg_len - CMSG_LEN(0)) / sizeof(int);
        for (size_t i = 0; i < n; i++) {
            int fd;
            memcpy(&fd, CMSG_DATA(h) + i * sizeof(int), sizeof fd);
            keep_fd(srv, c, fd);
        }
    }
    if (m.msg_flags & MSG_CTRUNC)   /* more than 8 at once: the kernel closed the rest */
        STS_STAT_ADD(srv, shm_fds_dropped, 1);
    return r;
}

/* The oldest descriptor the connection holds, -1 when none. */
static int take_fd(sts_conn *c)
{
    sts_shm_conn *s = c->shm;
    if (!s || !s->nfds)
        return -1;
    int fd = s->fds[0];
    memmove(s->fds, s->fds + 1, (s->nfds - 1) * sizeof s->fds[0]);
    s->nfds--;
    return fd;
}

void sts_shm_conn_free(sts_server *srv, sts_conn *c)
{
    sts_shm_conn *s = c->shm;
    if (!s)
        return;
    for (unsigned i = 0; i < s->nfds; i++)
        close(s->fds[i]);
    if (s->map) {
        munmap(s->map, (size_t)s->size);
        __atomic_sub_fetch(&srv->stats.shm_maps, 1, __ATOMIC_RELAXED);
        __atomic_sub_fetch(&srv->stats.shm_bytes, s->size, __ATOMIC_RELAXED);
    }
    free(s);
    c->shm = NULL;
}

void sts_shm_scratch_free(sts_shm_scratch *s)
{
    if (!s)
        return;
    free(s->q);
    free(s);
}

/* ---- SHM_ATTACH -------------------------------------------------------------------------------- */

/* Checks the descriptor and maps it; NULL with *status and msg set when refused. */
static uint8_t *map_region(int fd, uint64_t size, int *status, char *msg, size_t ml)
{
    struct stat st;
    struct statfs sf;
    *status = STP_S_INVALID;
    int seals = fcntl(fd, F_GET_SEALS);
    if (seals < 0 || fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        snprintf(msg, ml, "SHM_ATTACH: the descriptor is not a memfd (memfd_create with "
                 "MFD_ALLOW_SEALING)");
        return NULL;
    }
    if ((seals & (F_SEAL_SHRINK | F_SEAL_GROW)) != (F_SEAL_SHRINK | F_SEAL_GROW)) {
        snprintf(msg, ml, "SHM_ATTACH: the memfd must be sealed with F_SEAL_SHRINK and "
                 "F_SEAL_GROW (its seals are 0x%x)", (unsigned)seals);
        return NULL;
    }
    if (seals & (F_SEAL_WRITE | F_SEAL_FUTURE_WRITE)) {
        snprintf(msg, ml, "SHM_ATTACH: the memfd is sealed against writes: the daemon writes "
                 "replies into it");
        return NULL;
    }
    if ((uint64_t)st.st_size != size) {
        snprintf(msg, ml, "SHM_ATTACH: size %" PRIu64 " does not match the memfd's %lld bytes",
                 size, (long long)st.st_size);
        return NULL;
    }
    if (fstatfs(fd, &sf) == 0 && (unsigned long)sf.f_type == (unsigned long)HUGETLBFS_MAGIC_) {
        snprintf(msg, ml, "SHM_ATTACH: hugetlbfs memfds are refused (use MFD_ALLOW_SEALING "
                 "without MFD_HUGETLB)");
        return NULL;
    }
    void *p = mmap(NULL, (size_t)size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    if (p == MAP_FAILED) {
        *status = errno == ENOMEM ? STP_S_NOMEM : STP_S_INVALID;
        snprintf(msg, ml, "SHM_ATTACH: cannot map the memfd: %s", strerror(errno));
        return NULL;
    }
    *status = 0;
    return p;
}

int sts_h_shm_attach(sts_ctx *c, const stp_header *h, const uint8_t *body, stp_buf *out)
{
    sts_server *srv = c->srv;
    uint64_t size = 0, max = STS_LIVE(srv, shm_max);
    const char *why = NULL;
    int fd = take_fd(c->conn);   /* every SHM_ATTACH takes the oldest descriptor held */
    int status = 0;
    char msg[256];
    if (stp_dec_id_req(body, h->body_len, &size, &why) != 0) {
        status = STP_S_BAD_REQUEST;
        snprintf(msg, sizeof msg, "SHM_ATTACH: the body is one u64, the region's size");
    } else if (!c->conn->unix_sock) {
        status = STP_S_UNSUPPORTED;
        snprintf(msg, sizeof msg, "SHM_ATTACH needs a Unix-domain connection "
                 "(seamtexd --listen unix:PATH)");
    } else if (max == 0) {
        status = STP_S_UNSUPPORTED;
        snprintf(msg, sizeof msg, "shared memory is off on this server (shm-max 0)");
    } else if (fd < 0) {
        status = STP_S_INVALID;
        snprintf(msg, sizeof msg, "SHM_ATTACH: no file descriptor came with the frame (send "
                 "the memfd as SCM_RIGHTS on the frame's first byte)");
    } else if (c->conn->shm && c->conn->shm->map) {
        status = STP_S_EXISTS;
        snprintf(msg, sizeof msg, "SHM_ATTACH: a region of %" PRIu64 " bytes is already "
                 "attached to this connection", c->conn->shm->size);
    } else if (size == 0 || size > max || size > SIZE_MAX) {
        status = size ? STP_S_TOO_LARGE : STP_S_INVALID;
        snprintf(msg, sizeof msg, "SHM_ATTACH: region of %" PRIu64 " bytes: must be 1..%" PRIu64
                 " (shm-max)", size, max);
    }
    uint8_t *map = NULL;
    if (!status) {
        map = map_region(fd, size, &status, msg, sizeof msg);
        sts_shm_conn *s = map ? conn_shm(c->conn) : NULL;
        if (map && !s) {
            munmap(map, (size_t)size);
            status = STP_S_NOMEM;
            snprintf(msg, sizeof msg, "out of memory");
        } else if (map) {
            s->map = map;
            s->size = size;
        }
    }
    if (fd >= 0)
        close(fd);           /* the mapping keeps the memory; the descriptor is not needed */
    if (status) {
        STS_STAT_ADD(srv, shm_refused, 1);
        sts_reply_error(out, h, status, msg);
        return 0;
    }
    STS_STAT_ADD(srv, shm_attached, 1);
    STS_STAT_ADD(srv, shm_maps, 1);
    STS_STAT_ADD(srv, shm_bytes, size);
    stp_enc_id_reply(out, h->opcode, h->reqid, size);
    return 0;
}

/* ---- STATS -------------------------------------------------------------------------------------- */

size_t sts_shm_stats(sts_server *srv, stp_stat *s, size_t cap)
{
    const struct { const char *key; uint64_t v; } rows[STS_SHM_STAT_KEYS] = {
        {"shm_attached", __atomic_load_n(&srv->stats.shm_attached, __ATOMIC_RELAXED)},
        {"shm_refused", __atomic_load_n(&srv->stats.shm_refused, __ATOMIC_RELAXED)},
        {"shm_maps", __atomic_load_n(&srv->stats.shm_maps, __ATOMIC_RELAXED)},
        {"shm_bytes", __atomic_load_n(&srv->stats.shm_bytes, __ATOMIC_RELAXED)},
        {"shm_requests", __atomic_load_n(&srv->stats.shm_requests, __ATOMIC_RELAXED)},
        {"shm_too_small", __atomic_load_n(&srv->stats.shm_too_small, __ATOMIC_RELAXED)},
        {"shm_fds_dropped", __atomic_load_n(&srv->stats.shm_fds_dropped, __ATOMIC_RELAXED)},
        {"shm_overlap_copies",
         __atomic_load_n(&srv->stats.shm_overlap_copies, __ATOMIC_RELAXED)},
    };
    size_t n = 0;
    for (; n < STS_SHM_STAT_KEYS && n < cap; n++) {
        snprintf(s[n].key, sizeof s[n].key, "%s", rows[n].key);
        s[n].type = STP_STAT_U64;
        s[n].v.u = rows[n].v;
    }
    return n;
}
