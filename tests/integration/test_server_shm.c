/* tests/integration/test_server_shm.c - shared-memory sampling (PROTOCOL.md 4.12): results
 * through the region are bit for bit those of the socket path (blocking and pipelined, inline
 * and on a worker, f32 and compact queries, every reply format, SAMPLE_DIR on a cube; the
 * daemon samples them in place, and byte for byte the same when the rooms overlap or the
 * reply is unaligned); the zero-copy calls (stc_shm_reserve, stc_shm_append, stc_shm_sample)
 * give the same results as the copying ones; every hostile attach and
 * request gets its defined status while the daemon keeps serving (no descriptor, not a memfd,
 * unsealed, sealed against writes, size mismatch, over shm-max, a second attach, TCP,
 * offsets past the region or wrapping, a reply room too small); a client cannot shrink its
 * sealed region; a fuzz-ish loop of random offsets while another thread scribbles over the
 * region, and split batches sampled while another thread scribbles over their queries;
 * mappings counted in STATS and dropped at close.
 *
 * Each test starts its own daemon on a Unix socket (unix_daemon.h) with --heavy-batch 2048
 * (so 5000-query batches run on a worker and are split).
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/unix_daemon.h"
#include "../common/wait.h"
#include "../common/wire.h"
#include "../common/testdata.h"
#include "proto.h"
#include "shmfd.h"
#include "unixaddr.h"

static const char *const ARGS[] = {"--heavy-batch", "2048", NULL};

static stc_conn *client(const st_unix_daemon *u)
{
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 20000;
    int err = 0;
    char msg[256];
    stc_conn *c = stc_connect_opts(u->addr, 0, &o, &err, msg, sizeof msg);
    if (!c)
        fprintf(stderr, "connect %s: %s\n", u->addr, msg);
    return c;
}

static uint64_t stat_of(stc_conn *c, const char *key)
{
    return st_conn_stat(c, key);
}

/* ---- results ------------------------------------------------------------------------------- */

typedef struct copy {
    uint32_t count, nbad;
    unsigned nchan, outfmt;
    size_t   vbytes;
    uint8_t *values, *coverage, *status;
} copy;

static size_t value_size(unsigned outfmt)
{
    return outfmt == STC_OUT_UNORM8 ? 1 : outfmt == STC_OUT_UNORM16 ? 2 : 4;
}

static void take(const stc_sample_result *r, copy *o)
{
    o->count = r->count;
    o->nbad = r->nbad;
    o->nchan = r->nchan;
    o->outfmt = r->outfmt;
    o->vbytes = (size_t)r->count * r->nchan * value_size(r->outfmt);
    o->values = malloc(o->vbytes + 1);
    o->coverage = malloc((size_t)r->count * 4 + 1);
    o->status = malloc((size_t)r->count + 1);
    memcpy(o->values, r->values, o->vbytes);
    assert_non_null(r->coverage);
    assert_non_null(r->status);
    memcpy(o->coverage, r->coverage, (size_t)r->count * 4);
    memcpy(o->status, r->status, r->count);
}

static void same(const copy *a, const copy *b)
{
    assert_int_equal(a->count, b->count);
    assert_int_equal(a->nbad, b->nbad);
    assert_int_equal(a->nchan, b->nchan);
    assert_int_equal(a->outfmt, b->outfmt);
    assert_memory_equal(a->values, b->values, a->vbytes);      /* bits: NaN == NaN here */
    assert_memory_equal(a->coverage, b->coverage, (size_t)a->count * 4);
    assert_memory_equal(a->status, b->status, a->count);
}

static void drop(copy *o)
{
    free(o->values);
    free(o->coverage);
    free(o->status);
}

static void shm_results_are_bit_identical_to_the_socket_path(void **state)
{
    st_unix_daemon *u = *state;
    assert_int_equal(st_unix_start_args(u, "0600", ARGS), 0);
    stc_conn *plain = client(u), *shm = client(u);
    assert_non_null(plain);
    assert_non_null(shm);
    assert_true(stc_server_info(shm)->caps & STC_CAP_SHM);
    assert_int_equal(stc_shm_attach(shm, 4u << 20), 0);
    assert_int_equal(stc_shm_attach(shm, 4u << 20), STC_ESTATE);   /* one region per conn */
    assert_int_equal(stat_of(plain, "shm_maps"), 1);
    assert_int_equal(stat_of(plain, "shm_bytes"), 4u << 20);

    static const unsigned modes[] = {STP_MODE_DISCARD, STP_MODE_TRAVERSE, STP_MODE_CLAMP};
    static const unsigned filters[] = {STP_FILTER_POINT, STP_FILTER_BILINEAR,
                                       STP_FILTER_ANISO, STP_FILTER_PTEX_BILINEAR};
    static const unsigned outfmts[] = {STC_OUT_F32, STC_OUT_UNORM8, STC_OUT_UNORM16,
                                       STC_OUT_F16};
    static const unsigned layouts[] = {0, STC_WANT_UV16 | STC_WANT_FACE16, STC_WANT_UV16};
    static const size_t sizes[] = {1, 300, 5000};   /* inline; on a worker and split */
    size_t checked = 0;
    for (size_t si = 0; si < 3; si++) {
        stc_query *q = st_default_set_queries(sizes[si], 7 + (uint32_t)si);
        for (size_t mi = 0; mi < 3; mi++)
            for (size_t fi = 0; fi < 4; fi++) {
                stc_sample_opts o;
                memset(&o, 0, sizeof o);
                o.mode = modes[mi];
                o.filter = filters[fi];
                o.outfmt = outfmts[(mi + fi) % 4];
                o.want = STC_WANT_COVERAGE | STC_WANT_STATUS | layouts[(fi + si) % 3];
                stc_sample_result r;
                copy a, b;
                assert_int_equal(stc_sample(plain, "default", &o, q, sizes[si], &r), 0);
                take(&r, &a);
                assert_int_equal(stc_sample(shm, "default", &o, q, sizes[si], &r), 0);
                take(&r, &b);
                same(&a, &b);
                drop(&a);
                drop(&b);
                checked++;
            }
        free(q);
    }
    uint64_t via_shm = 0, via_sock = 0;
    stc_shm_counts(shm, &via_shm, &via_sock);
    assert_int_equal(via_shm, checked);
    assert_int_equal(via_sock, 0);
    assert_int_equal(stat_of(plain, "shm_requests"), checked);
    /* libseamtex gives every request disjoint rooms: all were sampled in place */
    assert_int_equal(stat_of(plain, "shm_overlap_copies"), 0);

    /* pipelined, on a connection with a small region (128 KiB; a request takes its queries
     * and its reply room): three requests in flight
     * share the ring, which wraps, and those that find no room go over the socket */
    stc_conn *small = client(u);
    assert_non_null(small);
    assert_int_equal(stc_shm_attach(small, 128u << 10), 0);
    stc_query *q = st_default_set_queries(4000, 99);
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = STP_MODE_TRAVERSE;
    o.filter = STP_FILTER_BILINEAR;
    o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
    copy want[6];
    for (int i = 0; i < 6; i++) {
        stc_sample_result r;
        assert_int_equal(stc_sample(plain, "default", &o, q + i * 500, 500 + 100 * i, &r), 0);
        take(&r, &want[i]);
    }
    enum { NREQ = 30, AHEAD = 3 };
    uint32_t ids[NREQ];
    for (int k = 0; k < NREQ + AHEAD; k++) {
        if (k < NREQ)
            assert_int_equal(stc_append_sample(small, "default", &o, q + (k % 6) * 500,
                                               500 + 100 * (k % 6), &ids[k]), 0);
        if (k < AHEAD)
            continue;
        int j = k - AHEAD;
        stc_reply rep;
        stc_sample_result r;
        copy got;
        assert_int_equal(stc_get_reply(small, -1, &rep), 0);
        assert_int_equal(rep.reqid, ids[j]);
        assert_int_equal(rep.status, 0);
        assert_int_equal(stc_reply_sample(small, &rep, &r), 0);
        take(&r, &got);
        same(&want[j % 6], &got);
        drop(&got);
    }
    for (int i = 0; i < 6; i++)
        drop(&want[i]);
    stc_shm_counts(small, &via_shm, &via_sock);
    printf("# small region: %llu via shm, %llu via the socket\n", (unsigned long long)via_shm,
           (unsigned long long)via_sock);
    assert_int_equal(via_shm + via_sock, NREQ);
    assert_true(via_shm > NREQ / 2);
    assert_true(via_sock > 0);
    stc_close(small);

    /* a batch larger than the region goes over the socket, same results */
    stc_query *big = st_default_set_queries(200000, 5);
    stc_sample_result r;
    copy a, b;
    assert_int_equal(stc_sample(plain, "default", &o, big, 200000, &r), 0);
    take(&r, &a);
    assert_int_equal(stc_sample(shm, "default", &o, big, 200000, &r), 0);
    take(&r, &b);
    same(&a, &b);
    drop(&a);
    drop(&b);
    stc_shm_counts(shm, NULL, &via_sock);
    assert_int_equal(via_sock, 1);
    free(big);

    /* SAMPLE_DIR on a cube map: every reply format, both footprints, inline and split */
    char path[1024];
    if (st_test_data_path(path, sizeof path, "env/StageEnvLatLong.exr") == 0) {
        stc_upload_opts uo;
        stc_upload_result up;
        memset(&uo, 0, sizeof uo);
        uo.options = "cube=latlong:64";
        assert_int_equal(stc_upload_file(plain, path, "env", &uo, &up), 0);
        for (size_t si = 0; si < 3; si++) {
            size_t n = sizes[si];
            stc_dir_query *dq = calloc(n, sizeof *dq);
            uint32_t seed = 31 + (uint32_t)si;
            for (size_t i = 0; i < n; i++) {
                for (int k = 0; k < 3; k++) {
                    dq[i].dir[k] = (float)st_rng_next(&seed) / 8388608.0f - 1.0f;
                    dq[i].ddx[k] = (float)(st_rng_next(&seed) % 100) / 4000.0f;
                    dq[i].ddy[k] = (float)(st_rng_next(&seed) % 100) / 4000.0f;
                }
                if (i % 97 == 5)
                    dq[i].dir[0] = dq[i].dir[1] = dq[i].dir[2] = 0;   /* not a direction */
            }
            for (unsigned fmt = 0; fmt < 4; fmt++) {
                stc_sample_opts od;
                memset(&od, 0, sizeof od);
                od.mode = STP_MODE_TRAVERSE;
                od.filter = fmt % 2 ? STP_FILTER_TRILINEAR : STP_FILTER_BILINEAR;
                od.outfmt = outfmts[fmt];
                od.footprint = fmt >= 2;
                od.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
                copy a, b;
                assert_int_equal(stc_sample_dir(plain, "env", &od, dq, n, &r), 0);
                take(&r, &a);
                assert_int_equal(stc_sample_dir(shm, "env", &od, dq, n, &r), 0);
                take(&r, &b);
                same(&a, &b);
                drop(&a);
                drop(&b);
            }
            free(dq);
        }
        assert_int_equal(stat_of(plain, "shm_overlap_copies"), 0);
    }

    /* errors travel as frames: SAMPLE_DIR on a per-face set, a bad set name */
    stc_dir_query d;
    memset(&d, 0, sizeof d);
    d.dir[0] = 1;
    assert_int_equal(stc_sample_dir(shm, "default", &o, &d, 1, &r), STC_EUNSUPPORTED);
    assert_int_equal(stc_sample(shm, "nosuchset", &o, q, 10, &r), STC_ENOTFOUND);
    assert_int_equal(stc_sample(shm, "default", &o, q, 10, &r), 0);
    free(q);

    stc_close(shm);
    assert_int_equal(st_wait_stat(&u->d, plain, "shm_maps", ST_STAT_EQ, 0, 10000), 0);
    assert_int_equal(stat_of(plain, "shm_bytes"), 0);
    stc_close(plain);
    assert_int_equal(st_unix_stop(u), 0);
}

/* ---- raw frames ------------------------------------------------------------------------------- */

static int raw_connect(const st_unix_daemon *u)
{
    struct sockaddr_un sa;
    socklen_t len;
    assert_int_equal(stu_unix_addr(u->addr, &sa, &len), 0);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    assert_true(fd >= 0);
    assert_int_equal(connect(fd, (struct sockaddr *)&sa, len), 0);
    return fd;
}

/* SHM_ATTACH announcing `size`, with descriptor passfd (< 0: none); the reply's status. */
static unsigned attach(int fd, uint64_t size, int passfd, st_wire_reply *r)
{
    uint8_t body[8], frame[64];
    stp_wr64(body, size);
    size_t n = st_wire_frame(frame, "STX1", 1, STP_OP_SHM_ATTACH, 0, 1, body, 8, 8);
    if (passfd >= 0)
        assert_int_equal(stu_send_with_fd(fd, frame, n, passfd), (ssize_t)n);
    else
        assert_int_equal(st_wire_send_all(fd, frame, n), 0);
    assert_int_equal(st_wire_read_reply(fd, r, 10000), 0);
    assert_int_equal(r->op, STP_OP_SHM_ATTACH);
    return r->status;
}

/* Starts u's daemon (ARGS), connects a raw socket and attaches a sealed region of sz bytes to
 * it (*mfd, *map: the memfd and its mapping). Returns the socket. */
static int raw_with_region(st_unix_daemon *u, size_t sz, int *mfd, void **map)
{
    assert_int_equal(st_unix_start_args(u, "0600", ARGS), 0);
    int fd = raw_connect(u);
    st_wire_reply r;
    assert_int_equal(stu_memfd_sealed("t", sz, mfd, map), 0);
    assert_int_equal(attach(fd, sz, *mfd, &r), STP_S_OK);
    return fd;
}

static void ping_ok(int fd)
{
    uint8_t frame[64];
    st_wire_reply r;
    size_t n = st_wire_frame(frame, "STX1", 1, STP_OP_PING, 0, 9, "hi", 2, 2);
    assert_int_equal(st_wire_send_all(fd, frame, n), 0);
    assert_int_equal(st_wire_read_reply(fd, &r, 10000), 0);
    assert_int_equal(r.status, 0);
    assert_int_equal(r.reqid, 9);
}

/* A shared-memory SAMPLE of `count` f32 queries of "default" (traverse, bilinear, f32,
 * coverage + status) with these offsets; claimed_len adds or removes bytes (0 = right). */
static unsigned shm_sample(int fd, uint32_t count, uint64_t qoff, uint64_t roff, uint64_t rcap,
                           int len_delta, st_wire_reply *r)
{
    uint8_t body[128], frame[200];
    stp_buf b;
    stp_buf_init(&b);
    stp_sample_req rq;
    memset(&rq, 0, sizeof rq);
    snprintf(rq.p.name, sizeof rq.p.name, "default");
    rq.p.mode = STP_MODE_TRAVERSE;
    rq.p.filter = STP_FILTER_BILINEAR;
    rq.p.flags = STP_SF_COVERAGE | STP_SF_STATUS | STP_SF_SHM;
    rq.count = count;
    rq.shm.query_off = qoff;
    rq.shm.reply_off = roff;
    rq.shm.reply_cap = rcap;
    assert_int_equal(stp_enc_sample_req(&b, 5, 0, &rq), 0);
    size_t len = stp_buf_avail(&b) - STP_HEADER_SIZE;
    assert_true(len <= sizeof body);
    memcpy(body, stp_buf_head(&b) + STP_HEADER_SIZE, len);
    stp_buf_free(&b);
    uint32_t claimed = (uint32_t)((int)len + len_delta);
    size_t n = st_wire_frame(frame, "STX1", 1, STP_OP_SAMPLE, 0, 5, body,
                             len_delta < 0 ? claimed : (uint32_t)len, claimed);
    if (len_delta > 0) {                 /* trailing bytes after the offsets */
        memset(frame + n, 0, (size_t)len_delta);
        n += (size_t)len_delta;
    }
    assert_int_equal(st_wire_send_all(fd, frame, n), 0);
    assert_int_equal(st_wire_read_reply(fd, r, 20000), 0);
    assert_int_equal(r->op, STP_OP_SAMPLE);
    assert_int_equal(r->reqid, 5);
    return r->status;
}

static void fill_queries(uint8_t *region, uint64_t off, uint32_t count)
{
    for (uint32_t i = 0; i < count; i++) {
        uint8_t *p = region + off + (size_t)i * STP_QUERY_SIZE;
        stp_wr32(p, i % 384);
        stp_wr32(p + 4, stp_f2u(0.25f + (float)(i % 7) / 16.0f));
        stp_wr32(p + 8, stp_f2u(0.5f));
        stp_wr32(p + 12, stp_f2u(0.01f));
        stp_wr32(p + 16, 0);
        stp_wr32(p + 20, 0);
        stp_wr32(p + 24, stp_f2u(0.01f));
    }
}

static void hostile_attaches_get_their_status_and_the_daemon_keeps_serving(void **state)
{
    st_unix_daemon *u = *state;
    assert_int_equal(st_unix_start_args(u, "0600", ARGS), 0);
    enum { SZ = 1 << 20 };
    st_wire_reply r;
    int fd = raw_connect(u), mfd;
    void *map;
    unsigned refused = 0;

    /* no descriptor */
    assert_int_equal(attach(fd, SZ, -1, &r), STP_S_INVALID);
    refused++;
    assert_non_null(strstr((char *)r.body, "no file descriptor"));
    ping_ok(fd);
    /* a pipe is not a memfd */
    int pp[2];
    assert_int_equal(pipe(pp), 0);
    assert_int_equal(attach(fd, SZ, pp[0], &r), STP_S_INVALID);
    refused++;
    assert_non_null(strstr((char *)r.body, "not a memfd"));
    close(pp[0]);
    close(pp[1]);
    /* a memfd without seals: it could be truncated under the daemon */
    int raw = memfd_create("t", MFD_CLOEXEC | MFD_ALLOW_SEALING);
    assert_true(raw >= 0);
    assert_int_equal(ftruncate(raw, SZ), 0);
    assert_int_equal(attach(fd, SZ, raw, &r), STP_S_INVALID);
    refused++;
    assert_non_null(strstr((char *)r.body, "F_SEAL_SHRINK"));
    /* sealed against shrinking only */
    assert_int_equal(fcntl(raw, F_ADD_SEALS, F_SEAL_SHRINK), 0);
    assert_int_equal(attach(fd, SZ, raw, &r), STP_S_INVALID);
    refused++;
    /* sealed, but against writes too: the daemon could not write replies */
    assert_int_equal(fcntl(raw, F_ADD_SEALS, F_SEAL_GROW | F_SEAL_WRITE), 0);
    assert_int_equal(attach(fd, SZ, raw, &r), STP_S_INVALID);
    refused++;
    assert_non_null(strstr((char *)r.body, "against writes"));
    close(raw);
    /* a size that is not the memfd's */
    assert_int_equal(stu_memfd_sealed("t", SZ, &mfd, &map), 0);
    assert_int_equal(attach(fd, SZ / 2, mfd, &r), STP_S_INVALID);
    refused++;
    assert_non_null(strstr((char *)r.body, "does not match"));
    /* over shm-max (256 MiB by default), and 0 */
    assert_int_equal(attach(fd, (uint64_t)1 << 40, mfd, &r), STP_S_TOO_LARGE);
    refused++;
    assert_int_equal(attach(fd, 0, mfd, &r), STP_S_INVALID);
    refused++;
    ping_ok(fd);
    /* a flag SHM request before any region */
    assert_int_equal(shm_sample(fd, 1, 0, 0, 4096, 0, &r), STP_S_INVALID);
    assert_non_null(strstr((char *)r.body, "SHM_ATTACH first"));
    /* the right one, then a second */
    assert_int_equal(attach(fd, SZ, mfd, &r), STP_S_OK);
    assert_int_equal(r.len, 8);
    assert_int_equal(stp_rd64(r.body), SZ);
    assert_int_equal(attach(fd, SZ, mfd, &r), STP_S_EXISTS);
    refused++;
    /* the client cannot shrink (or grow) what the daemon has mapped */
    assert_int_equal(ftruncate(mfd, SZ / 2), -1);
    assert_int_equal(errno, EPERM);
    assert_int_equal(ftruncate(mfd, SZ * 2), -1);
    assert_int_equal(errno, EPERM);
    uint8_t *region = map;
    fill_queries(region, 4096, 100);
    assert_int_equal(shm_sample(fd, 100, 4096, 65536, 65536, 0, &r), STP_S_OK);
    assert_int_equal(r.len, STP_SHM_REPLY_SIZE);
    assert_int_equal(stp_rd64(r.body), 65536);
    uint64_t rlen = stp_rd64(r.body + 8);
    assert_int_equal(rlen, 12 + 100 * (4 * 4 + 4 + 1));
    stp_sample_reply rp;
    const char *why = NULL;
    assert_int_equal(stp_dec_sample_reply(region + 65536, rlen, &rp, &why), 0);
    assert_int_equal(rp.count, 100);
    assert_int_equal(rp.nbad, 0);

    /* hostile offsets: each its status, the connection goes on */
    assert_int_equal(shm_sample(fd, 100, SZ - 100, 0, 4096, 0, &r), STP_S_INVALID);  /* past */
    assert_non_null(strstr((char *)r.body, "outside the region"));
    assert_int_equal(shm_sample(fd, 100, UINT64_MAX - 100, 0, 4096, 0, &r), STP_S_INVALID);
    assert_int_equal(shm_sample(fd, 1, SZ, 0, 4096, 0, &r), STP_S_INVALID);   /* at the end */
    assert_int_equal(shm_sample(fd, 0, SZ, 0, 4096, 0, &r), STP_S_OK);        /* 0 bytes: ok */
    assert_int_equal(shm_sample(fd, 1, 0, SZ - 10, 4096, 0, &r), STP_S_INVALID);
    assert_int_equal(shm_sample(fd, 1, 0, 8, UINT64_MAX, 0, &r), STP_S_INVALID); /* wraps */
    assert_int_equal(shm_sample(fd, 1, 0, UINT64_MAX, 1, 0, &r), STP_S_INVALID);
    assert_int_equal(shm_sample(fd, 100, 4096, 0, 100, 0, &r), STP_S_TOO_LARGE); /* room */
    assert_non_null(strstr((char *)r.body, "reply needs"));
    assert_int_equal(shm_sample(fd, 100, 4096, 0, 4096, 4, &r), STP_S_BAD_REQUEST);
    assert_int_equal(shm_sample(fd, 100, 4096, 0, 4096, -4, &r), STP_S_BAD_REQUEST);
    assert_int_equal(shm_sample(fd, 2000000, 0, 0, 4096, 0, &r), STP_S_TOO_LARGE); /* batch */
    ping_ok(fd);
    assert_int_equal(shm_sample(fd, 100, 4096, 65536, 65536, 0, &r), STP_S_OK);

    /* the counters; a STATS over libseamtex */
    stc_conn *c = client(u);
    assert_non_null(c);
    assert_int_equal(stat_of(c, "shm_refused"), refused);
    assert_int_equal(stat_of(c, "shm_attached"), 1);
    assert_int_equal(stat_of(c, "shm_maps"), 1);
    assert_int_equal(stat_of(c, "shm_too_small"), 1);
    /* SHM_ATTACH and flag SHM over TCP are refused: checked below on a TCP daemon */
    close(fd);
    assert_int_equal(st_wait_stat(&u->d, c, "shm_maps", ST_STAT_EQ, 0, 10000), 0);
    stc_close(c);
    munmap(map, SZ);
    close(mfd);
    assert_int_equal(st_unix_stop(u), 0);
}

static void shm_is_refused_over_tcp(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_up(&d, NULL), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    assert_false(stc_server_info(c)->caps & STC_CAP_SHM);   /* not offered over TCP */
    assert_int_equal(stc_shm_attach(c, 1 << 20), STC_EINVAL);
    int fd = st_daemon_connect(&d);
    assert_true(fd >= 0);
    st_wire_reply r;
    assert_int_equal(attach(fd, 1 << 20, -1, &r), STP_S_UNSUPPORTED);
    assert_non_null(strstr((char *)r.body, "Unix-domain"));
    assert_int_equal(shm_sample(fd, 1, 0, 0, 4096, 0, &r), STP_S_INVALID);
    assert_non_null(strstr((char *)r.body, "Unix-domain"));
    ping_ok(fd);
    close(fd);
    stc_close(c);
    assert_int_equal(st_daemon_down(&d, 20000), 0);
}


/* ---- zero-copy calls ------------------------------------------------------------------------ */

static void zero_copy_calls_match_the_copying_ones(void **state)
{
    st_unix_daemon *u = *state;
    assert_int_equal(st_unix_start_args(u, "0600", ARGS), 0);
    stc_conn *plain = client(u), *c = client(u);
    assert_non_null(plain);
    assert_non_null(c);
    void *qp = NULL;
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = STP_MODE_TRAVERSE;
    o.filter = STP_FILTER_BILINEAR;
    o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
    /* no region yet */
    assert_int_equal(stc_shm_reserve(c, "default", &o, 0, 10, &qp), STC_ESTATE);
    assert_null(qp);
    assert_int_equal(stc_shm_attach(c, 2u << 20), 0);
    enum { N = 5000 };
    stc_query *q = st_default_set_queries(N, 41);
    static const unsigned outfmts[] = {STC_OUT_F32, STC_OUT_UNORM8, STC_OUT_UNORM16,
                                       STC_OUT_F16};
    for (unsigned k = 0; k < 8; k++) {
        o.outfmt = outfmts[k % 4];
        o.want = STC_WANT_COVERAGE | STC_WANT_STATUS |
                 (k >= 4 ? STC_WANT_UV16 | STC_WANT_FACE16 : 0);
        size_t n = k % 2 ? N : 77;
        stc_sample_result r;
        copy a, b;
        assert_int_equal(stc_sample(plain, "default", &o, q, n, &r), 0);
        take(&r, &a);
        assert_int_equal(stc_shm_reserve(c, "default", &o, 0, n, &qp), 0);
        assert_non_null(qp);
        assert_int_equal((uintptr_t)qp % 64, 0);
        /* the caller writes the wire layout itself (stp_put_queries: the reference encoder) */
        stp_sample_req rq;
        memset(&rq, 0, sizeof rq);
        rq.p.flags = (uint8_t)o.want;
        rq.count = (uint32_t)n;
        rq.queries = (const stp_query *)q;
        stp_put_queries(STP_OP_SAMPLE, &rq, qp);
        assert_int_equal(stc_shm_sample(c, &r), 0);
        take(&r, &b);
        same(&a, &b);
        drop(&a);
        drop(&b);
    }
    /* pipelined: three reservations in flight, the f32 layout written as stc_query[] */
    o.outfmt = STC_OUT_F32;
    o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
    copy want[3];
    for (int i = 0; i < 3; i++) {
        stc_sample_result r;
        assert_int_equal(stc_sample(plain, "default", &o, q + i * 1000, 1000 + 500 * i, &r), 0);
        take(&r, &want[i]);
    }
    uint32_t ids[12], extra = 0;
    for (int k = 0; k < 12 + 3; k++) {
        if (k < 12) {
            int i = k % 3;
            assert_int_equal(stc_shm_reserve(c, "default", &o, 0, 1000 + 500 * i, &qp), 0);
            memcpy(qp, q + i * 1000, (1000 + 500 * (size_t)i) * sizeof(stc_query));
            /* while a reservation is open, a copying SAMPLE goes over the socket (its reply
             * comes in order, before request 4's) */
            if (k == 4) {
                uint64_t s0 = 0, s1 = 0;
                stc_shm_counts(c, NULL, &s0);
                assert_int_equal(stc_shm_reserve(c, "default", &o, 0, 1, &qp), STC_ESTATE);
                assert_int_equal(stc_append_sample(c, "default", &o, q, 1000, &extra), 0);
                stc_shm_counts(c, NULL, &s1);
                assert_int_equal(s1, s0 + 1);
            }
            assert_int_equal(stc_shm_append(c, &ids[k]), 0);
        }
        if (k < 3)
            continue;
        int j = k - 3;
        stc_reply rep;
        stc_sample_result r;
        copy got;
        if (j == 4) {                         /* the socket SAMPLE appended before request 4 */
            assert_int_equal(stc_get_reply(c, -1, &rep), 0);
            assert_int_equal(rep.reqid, extra);
            assert_int_equal(stc_reply_sample(c, &rep, &r), 0);
            take(&r, &got);
            same(&want[0], &got);
            drop(&got);
        }
        assert_int_equal(stc_get_reply(c, -1, &rep), 0);
        assert_int_equal(rep.reqid, ids[j]);
        assert_int_equal(stc_reply_sample(c, &rep, &r), 0);
        take(&r, &got);
        same(&want[j % 3], &got);
        drop(&got);
    }
    for (int i = 0; i < 3; i++)
        drop(&want[i]);
    /* misuse: nothing open, too many queries, more than the region holds, cancel */
    uint32_t id;
    assert_int_equal(stc_shm_append(c, &id), STC_ESTATE);
    assert_int_equal(stc_shm_reserve(c, "default", &o, 0,
                                     (size_t)stc_server_info(c)->max_batch + 1, &qp),
                     STC_EINVAL);
    assert_int_equal(stc_shm_reserve(c, "default", &o, 0, 60000, &qp), STC_ESTATE);  /* 2 MiB */
    assert_int_equal(stc_shm_reserve(c, "default", &o, 1, 10, &qp), 0);
    void *first = qp;
    stc_shm_cancel(c);
    assert_int_equal(stc_shm_reserve(c, "default", &o, 0, 10, &qp), 0);
    assert_ptr_equal(qp, first);             /* the cancelled room is handed out again */
    stc_shm_cancel(c);
    stc_shm_cancel(c);                       /* none open: nothing happens */
    assert_int_equal(stc_error(c), 0);
    assert_int_equal(stc_ping(c), 0);
    free(q);
    stc_close(c);
    stc_close(plain);
    assert_int_equal(st_unix_stop(u), 0);
}

/* ---- in place, overlapping, unaligned: the bytes the socket path gives ------------------ */

/* A shared-memory SAMPLE of rq (its parameters, count and offsets; flag SHM added) on fd. */
static unsigned shm_request(int fd, stp_sample_req *rq, st_wire_reply *r)
{
    uint8_t frame[300];
    stp_buf b;
    stp_buf_init(&b);
    rq->p.flags |= STP_SF_SHM;
    assert_int_equal(stp_enc_sample_req(&b, 6, 0, rq), 0);
    rq->p.flags &= (uint8_t)~STP_SF_SHM;
    size_t len = stp_buf_avail(&b) - STP_HEADER_SIZE;
    size_t n = st_wire_frame(frame, "STX1", 1, STP_OP_SAMPLE, 0, 6,
                             stp_buf_head(&b) + STP_HEADER_SIZE, (uint32_t)len, (uint32_t)len);
    stp_buf_free(&b);
    assert_int_equal(st_wire_send_all(fd, frame, n), 0);
    assert_int_equal(st_wire_read_reply(fd, r, 20000), 0);
    assert_int_equal(r->reqid, 6);
    return r->status;
}

static void rooms_in_place_overlapping_or_unaligned_give_the_socket_bytes(void **state)
{
    st_unix_daemon *u = *state;
    enum { SZ = 4 << 20, N = 5000, QOFF = 8192 };
    int mfd;
    void *map;
    int fd = raw_with_region(u, SZ, &mfd, &map);
    st_wire_reply r;
    uint8_t *region = map;
    stc_conn *plain = client(u);
    assert_non_null(plain);
    stc_query *q = st_default_set_queries(N, 3);
    /* reply rooms: disjoint and aligned, disjoint at an odd offset, the queries' own room,
     * overlapping the queries' second half at an odd offset */
    const uint64_t rooms[] = {2u << 20, (2u << 20) + 1, QOFF, QOFF + N * 7 + 3};
    const int overlaps[] = {0, 0, 1, 1};
    static const uint8_t outfmts[] = {STP_OUT_F32, STP_OUT_UNORM8, STP_OUT_UNORM16, STP_OUT_F16};
    static const uint8_t wants[] = {STP_SF_COVERAGE | STP_SF_STATUS, 0, STP_SF_STATUS,
                                    STP_SF_COVERAGE | STP_SF_UV16 | STP_SF_FACE16};
    uint64_t copies = 0;
    for (unsigned fi = 0; fi < 4; fi++)
        for (unsigned wi = 0; wi < 4; wi++) {
            stp_sample_req rq;
            memset(&rq, 0, sizeof rq);
            snprintf(rq.p.name, sizeof rq.p.name, "default");
            rq.p.mode = STP_MODE_TRAVERSE;
            rq.p.filter = (fi + wi) % 2 ? STP_FILTER_BILINEAR : STP_FILTER_ANISO;
            rq.p.outfmt = outfmts[fi];
            rq.p.flags = wants[wi];
            rq.count = N;
            rq.queries = (const stp_query *)q;
            /* the socket path's reply body */
            stp_buf b;
            stp_buf_init(&b);
            assert_int_equal(stp_enc_sample_req(&b, 1, 0, &rq), 0);
            uint32_t id;
            stc_reply rep;
            assert_int_equal(stc_append_raw(plain, STP_OP_SAMPLE,
                                            stp_buf_head(&b) + STP_HEADER_SIZE,
                                            stp_buf_avail(&b) - STP_HEADER_SIZE, &id), 0);
            stp_buf_free(&b);
            assert_int_equal(stc_get_reply(plain, -1, &rep), 0);
            assert_int_equal(rep.status, 0);
            uint8_t *want = malloc(rep.body_len);
            memcpy(want, rep.body, rep.body_len);
            size_t wlen = rep.body_len;
            for (unsigned ri = 0; ri < 4; ri++) {
                /* the room first (it may cover queries), then the queries */
                memset(region + rooms[ri], 0xA5, wlen);
                stp_put_queries(STP_OP_SAMPLE, &rq, region + QOFF);
                rq.shm.query_off = QOFF;
                rq.shm.reply_off = rooms[ri];
                rq.shm.reply_cap = SZ - rooms[ri];
                assert_int_equal(shm_request(fd, &rq, &r), STP_S_OK);
                assert_int_equal(stp_rd64(r.body), rooms[ri]);
                assert_int_equal(stp_rd64(r.body + 8), wlen);
                assert_memory_equal(region + rooms[ri], want, wlen);
                copies += (uint64_t)overlaps[ri];
            }
            free(want);
        }
    assert_int_equal(stat_of(plain, "shm_overlap_copies"), copies);
    free(q);
    stc_close(plain);
    close(fd);
    munmap(map, SZ);
    close(mfd);
    assert_int_equal(st_unix_stop(u), 0);
}

/* ---- fuzz-ish: random offsets while the region is rewritten ------------------------------- */

typedef struct scribbler {
    uint8_t *region;
    size_t   size;     /* it writes inside [0, size) of region */
    int      stop;
} scribbler;

static void *scribble(void *arg)
{
    scribbler *s = arg;
    uint32_t seed = 12345;
    while (!__atomic_load_n(&s->stop, __ATOMIC_RELAXED)) {
        size_t at = st_rng_next(&seed) % (s->size - 64);
        for (int i = 0; i < 64; i += 4) {
            uint32_t v = st_rng_next(&seed);
            /* faces, floats, NaNs, huge values: whatever the daemon reads must be safe */
            memcpy(s->region + at + i, &v, 4);
        }
    }
    return NULL;
}

static uint64_t pick_offset(uint32_t *seed, uint64_t size)
{
    switch (st_rng_next(seed) % 6) {
    case 0: return st_rng_next(seed) % (size + 1);
    case 1: return size - st_rng_next(seed) % 64;
    case 2: return size + st_rng_next(seed) % 64;
    case 3: return UINT64_MAX - st_rng_next(seed) % 64;
    case 4: return (uint64_t)st_rng_next(seed) << 32 | st_rng_next(seed);
    default: return (st_rng_next(seed) % 16) * 4096;
    }
}

static void random_offsets_never_hurt_the_daemon(void **state)
{
    st_unix_daemon *u = *state;
    enum { SZ = 1 << 20 };
    int mfd;
    void *map;
    int fd = raw_with_region(u, SZ, &mfd, &map);
    st_wire_reply r;
    scribbler s = {map, SZ, 0};
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, scribble, &s), 0);
    uint32_t seed = 777;
    unsigned ok = 0, invalid = 0, small = 0;
    for (int i = 0; i < 1500; i++) {
        uint32_t count = st_rng_next(&seed) % 3 ? st_rng_next(&seed) % 3000 : st_rng_next(&seed) % 40000;
        uint64_t qoff = pick_offset(&seed, SZ), roff = pick_offset(&seed, SZ);
        uint64_t rcap = st_rng_next(&seed) % 2 ? pick_offset(&seed, SZ) : SZ - roff % SZ;
        unsigned st = shm_sample(fd, count, qoff, roff, rcap, 0, &r);
        if (st == STP_S_OK) {
            ok++;
            assert_int_equal(r.len, STP_SHM_REPLY_SIZE);
            uint64_t off = stp_rd64(r.body), len = stp_rd64(r.body + 8);
            assert_true(off == roff && len <= rcap && stp_shm_range_ok(SZ, off, len));
            assert_int_equal(len, 12 + (uint64_t)count * 21);
        } else if (st == STP_S_INVALID) {
            invalid++;
            int q_in = stp_shm_range_ok(SZ, qoff, (uint64_t)count * STP_QUERY_SIZE);
            int r_in = stp_shm_range_ok(SZ, roff, rcap);
            assert_false(q_in && r_in);
        } else {
            assert_int_equal(st, STP_S_TOO_LARGE);
            small++;
        }
    }
    __atomic_store_n(&s.stop, 1, __ATOMIC_RELAXED);
    pthread_join(th, NULL);
    assert_true(ok > 0 && invalid > 0 && small > 0);   /* every branch was taken */
    ping_ok(fd);
    close(fd);
    munmap(map, SZ);
    close(mfd);
    assert_int_equal(st_unix_stop(u), 0);    /* a clean exit: nothing broke inside */
}


static void scribbling_over_split_batches_never_hurts_the_daemon(void **state)
{
    st_unix_daemon *u = *state;
    enum { SZ = 2 << 20, N = 20000, ROOM = 1 << 20 };     /* N over split-batch (2048) */
    int mfd;
    void *map;
    int fd = raw_with_region(u, SZ, &mfd, &map);
    st_wire_reply r;
    uint8_t *region = map;
    stc_conn *plain = client(u);
    assert_non_null(plain);
    uint64_t split0 = stat_of(plain, "split_batches");
    stc_query *q = st_default_set_queries(N, 8);
    stp_sample_req rq;
    memset(&rq, 0, sizeof rq);
    snprintf(rq.p.name, sizeof rq.p.name, "default");
    rq.p.mode = STP_MODE_TRAVERSE;
    rq.p.filter = STP_FILTER_BILINEAR;
    rq.p.flags = STP_SF_COVERAGE | STP_SF_STATUS;
    rq.count = N;
    rq.queries = (const stp_query *)q;
    rq.shm.query_off = 0;
    rq.shm.reply_off = ROOM;
    rq.shm.reply_cap = ROOM;
    const uint64_t rlen = 12 + (uint64_t)N * 21;
    /* another thread rewrites the queries (faces, NaNs, huge values) all the time */
    scribbler sc = {region, (size_t)N * STP_QUERY_SIZE, 0};
    stp_put_queries(STP_OP_SAMPLE, &rq, region);
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, scribble, &sc), 0);
    for (int i = 0; i < 3; i++) {
        for (unsigned fmt = 0; fmt < 4; fmt++) {
            rq.p.outfmt = (uint8_t)fmt;
            assert_int_equal(shm_request(fd, &rq, &r), STP_S_OK);
            uint64_t len = stp_rd64(r.body + 8);
            assert_int_equal(stp_rd64(r.body), ROOM);
            assert_int_equal(len, stp_sample_reply_bytes(N, 4, (uint8_t)fmt, rq.p.flags));
            stp_sample_reply rp;
            const char *why = NULL;
            assert_int_equal(stp_dec_sample_reply(region + ROOM, len, &rp, &why), 0);
            assert_int_equal(rp.count, N);
            assert_true(rp.nbad <= N);
        }
        /* the compact and direction-free f32 forms too; and overlapping rooms (copied
         * whole first) */
        rq.p.outfmt = STP_OUT_F32;
        rq.shm.reply_off = 0;
        assert_int_equal(shm_request(fd, &rq, &r), STP_S_OK);
        rq.shm.reply_off = ROOM;
        rq.p.flags |= STP_SF_UV16 | STP_SF_FACE16;
        assert_int_equal(shm_request(fd, &rq, &r), STP_S_OK);
        rq.p.flags &= (uint8_t)~(STP_SF_UV16 | STP_SF_FACE16);
    }
    __atomic_store_n(&sc.stop, 1, __ATOMIC_RELAXED);
    pthread_join(th, NULL);
    /* with the queries left alone, the same request gives the socket path's bytes */
    rq.p.outfmt = STP_OUT_F32;
    stp_put_queries(STP_OP_SAMPLE, &rq, region);
    assert_int_equal(shm_request(fd, &rq, &r), STP_S_OK);
    assert_int_equal(stp_rd64(r.body + 8), rlen);
    stc_sample_result res;
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = STP_MODE_TRAVERSE;
    o.filter = STP_FILTER_BILINEAR;
    o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
    assert_int_equal(stc_sample(plain, "default", &o, q, N, &res), 0);
    assert_int_equal(stp_rd32(region + ROOM), N);
    assert_int_equal(stp_rd32(region + ROOM + 8), res.nbad);
    assert_memory_equal(region + ROOM + 12, res.values, (size_t)N * 16);
    assert_memory_equal(region + ROOM + 12 + (size_t)N * 16, res.coverage, (size_t)N * 4);
    assert_memory_equal(region + ROOM + 12 + (size_t)N * 20, res.status, N);
    /* with two CPUs or more helpers took parts of those batches */
    if (sysconf(_SC_NPROCESSORS_ONLN) >= 2)
        assert_true(stat_of(plain, "split_batches") > split0);
    ping_ok(fd);
    free(q);
    stc_close(plain);
    close(fd);
    munmap(map, SZ);
    close(mfd);
    assert_int_equal(st_unix_stop(u), 0);    /* a clean exit: nothing broke inside */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(shm_results_are_bit_identical_to_the_socket_path,
                                        st_unix_setup, st_unix_teardown),
        cmocka_unit_test_setup_teardown(
            hostile_attaches_get_their_status_and_the_daemon_keeps_serving, st_unix_setup,
            st_unix_teardown),
        cmocka_unit_test(shm_is_refused_over_tcp),
        cmocka_unit_test_setup_teardown(random_offsets_never_hurt_the_daemon, st_unix_setup,
                                        st_unix_teardown),
        cmocka_unit_test_setup_teardown(zero_copy_calls_match_the_copying_ones, st_unix_setup,
                                        st_unix_teardown),
        cmocka_unit_test_setup_teardown(
            rooms_in_place_overlapping_or_unaligned_give_the_socket_bytes, st_unix_setup,
            st_unix_teardown),
        cmocka_unit_test_setup_teardown(scribbling_over_split_batches_never_hurts_the_daemon,
                                        st_unix_setup, st_unix_teardown),
    };
    return cmocka_run_group_tests_name("server_shm", tests, NULL, NULL);
}
