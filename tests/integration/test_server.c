/* tests/integration/test_server.c - seamtexd driven through libseamtex and raw sockets:
 * every request, pipelining, the malformed-frame table, limits, the token, reload, restart
 * with a data dir, graceful stop.
 *
 * Each group starts its own daemon (tests/common/daemon_fixture.h) on 127.0.0.1 port 0 with a
 * temp data dir. Upload data is made in-process (the built-in default set written as .ptx),
 * so nothing here needs SEAMTEX_DATA.
 */
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_fixture.h"
#include "defaultset.h"
#include "proto.h"
#include "ptex.h"
#include "sample.h"
#include "seamtex.h"

/* ---- helpers --------------------------------------------------------------------------------- */

static stc_conn *conn_to(const st_daemon *d, const char *token)
{
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 20000;
    o.token = token;
    int err = 0;
    char msg[256] = "";
    stc_conn *c = stc_connect_opts(d->host, (unsigned)d->port, &o, &err, msg, sizeof msg);
    if (!c)
        fprintf(stderr, "connect: %s %s\n", stc_strerror(err), msg);
    return c;
}

/* The default set as a .ptx in memory (malloc'ed), optionally with face 0 painted `tint`. */
static void *make_ptx(size_t *len, int tint)
{
    st_set *s = NULL;
    st_error e;
    if (st_default_set(&s, &e) != 0) {
        fprintf(stderr, "default set: %s\n", e.msg);
        return NULL;
    }
    if (tint >= 0) {
        uint8_t *t = st_face_level(s, 0, 0);
        size_t n = (size_t)s->faces[0].w * s->faces[0].h * st_texel_size(s);
        for (size_t i = 0; i < n; i++)
            t[i] = (uint8_t)(tint * 37 + i);
        st_set_build_mips(s, 0);
    }
    void *buf = NULL;
    if (st_ptex_write_mem(s, &buf, len, &e) != 0) {
        fprintf(stderr, "ptex write: %s\n", e.msg);
        buf = NULL;
    }
    st_set_free(s);
    return buf;
}

/* Four 32x32 RGBA8 faces without neighbours (every face one size: DDS can hold its BC1 form)
 * as a .ptx in memory. */
static void *make_uniform_ptx(size_t *len)
{
    st_set_info info;
    memset(&info, 0, sizeof info);
    info.nfaces = 4;
    info.nchan = 4;
    info.dtype = ST_DT_U8;
    info.alpha_chan = 3;
    st_face_desc fd[4];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 4; f++) {
        fd[f].w = fd[f].h = 32;
        for (int e = 0; e < 4; e++)
            fd[f].adjface[e] = -1;
    }
    st_set *s = NULL;
    st_error e;
    if (st_set_create(&info, fd, 0, &s, &e) != 0)
        return NULL;
    for (size_t i = 0; i < s->texel_bytes; i++)
        s->texels[i] = (uint8_t)(i * 13 + (i >> 7));
    st_set_build_mips(s, UINT32_MAX);
    void *buf = NULL;
    if (st_ptex_write_mem(s, &buf, len, &e) != 0)
        buf = NULL;
    st_set_free(s);
    return buf;
}

static int64_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

/* raw frames */
static size_t put_frame(uint8_t *out, const char *magic, unsigned version, unsigned op,
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
        memcpy(out + 24, body, len);
    return 24 + (size_t)len;
}

static int send_all(int fd, const void *p, size_t n)
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

typedef struct rawreply {
    unsigned op, flags, status;
    uint32_t reqid, len;
    uint8_t  body[4096];
} rawreply;

/* Reads one reply frame (body cut to 4096). 0, or -1 on timeout / close. */
static int read_reply(int fd, rawreply *r, int timeout_ms)
{
    uint8_t hdr[24];
    size_t got = 0;
    int64_t end = now_ms() + timeout_ms;
    uint32_t need = 24;
    uint8_t *dst = hdr;
    for (int phase = 0; phase < 2; phase++) {
        while (got < need) {
            struct pollfd p = {fd, POLLIN, 0};
            int left = (int)(end - now_ms());
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

/* 1 when the peer closed the socket within timeout_ms (nothing more to read). */
static int peer_closed(int fd, int timeout_ms)
{
    struct pollfd p = {fd, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0)
        return 0;
    uint8_t b[256];
    return recv(fd, b, sizeof b, MSG_DONTWAIT) == 0;
}

/* SAMPLE body for set `name` with n queries (caller-owned buffer of enough bytes). */
static size_t sample_body(uint8_t *out, const char *name, uint32_t claimed_count,
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

/* ---- group 1: one daemon with defaults, every request ---------------------------------------- */

static st_daemon D1;

static int setup_default(void **state)
{
    (void)state;
    const char *extra[] = {"--heavy-batch", "2048", NULL};
    if (st_daemon_init(&D1) != 0 || st_daemon_start(&D1, extra) != 0)
        return -1;
    return 0;
}

static int teardown_default(void **state)
{
    (void)state;
    int rc = st_daemon_stop(&D1, 15000);
    st_daemon_cleanup(&D1);
    return rc == 0 ? 0 : -1;
}

static void hello_reports_limits_and_caps(void **state)
{
    (void)state;
    stc_conn *c = conn_to(&D1, NULL);
    assert_non_null(c);
    const stc_server *s = stc_server_info(c);
    assert_int_equal(s->version, 1);
    assert_true(s->caps & STP_CAP_PIPELINE);
    assert_false(s->caps & STP_CAP_OUT_OF_ORDER);
    assert_false(s->caps & STP_CAP_AUTH);
    assert_int_equal(s->max_body, 64u << 20);
    assert_true(s->max_batch >= 4096);
    assert_non_null(strstr(s->name, "seamtexd"));
    stc_close(c);
}

static void ping_list_info_stats_answer(void **state)
{
    (void)state;
    stc_conn *c = conn_to(&D1, NULL);
    assert_non_null(c);
    assert_int_equal(stc_ping(c), 0);
    const stc_set_entry *sets;
    size_t n = 0;
    assert_int_equal(stc_list(c, &sets, &n), 0);
    int found = 0;
    for (size_t i = 0; i < n; i++)
        if (!strcmp(sets[i].name, "default")) {
            found = 1;
            assert_int_equal(sets[i].nfaces, 384);
            assert_int_equal(sets[i].nchan, 4);
        }
    assert_true(found);
    stc_info info;
    assert_int_equal(stc_info_get(c, "default", 0, 8, &info), 0);
    assert_int_equal(info.nfaces, 384);
    assert_int_equal(info.nrec, 8);
    assert_int_equal(info.boundary_edges, 0);      /* a closed cube */
    assert_true(info.irregular_corners > 0);        /* the 8 cube corners have valence 3 */
    assert_int_equal(info.max_valence, 4);
    assert_true(info.faces[0].w >= 16 && info.faces[0].w <= 64);
    assert_int_equal(stc_info_get(c, "nope", 0, 0, &info), STC_ENOTFOUND);
    assert_int_equal(stc_info_get(c, "../etc", 0, 0, &info), STC_EINVAL);  /* client refuses */
    const stc_stat *st;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    const stc_stat *req = stc_stat_find(st, n, "requests");
    assert_non_null(req);
    assert_true(req->u >= 3);
    assert_non_null(stc_stat_find(st, n, "conns_current"));
    assert_non_null(stc_stat_find(st, n, "req_ping"));
    stc_close(c);
}

static void sample_matches_in_process_sampler(void **state)
{
    (void)state;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_default_set(&s, &e), 0);
    enum { N = 5000 };  /* over --heavy-batch 2048: runs on a worker */
    stc_query *q = calloc(N, sizeof *q);
    st_query *sq = calloc(N, sizeof *sq);
    float *want = calloc((size_t)N * 4, sizeof *want);
    assert_non_null(q);
    srand(7);
    for (int i = 0; i < N; i++) {
        q[i].face = (uint32_t)(rand() % 384);
        q[i].u = (float)rand() / (float)RAND_MAX;
        q[i].v = (float)rand() / (float)RAND_MAX;
        q[i].dudx = q[i].dvdy = 0.01f;
        memcpy(&sq[i], &q[i], sizeof sq[i]);
    }
    st_sample_opts so = {ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, 0, 0, 0, 0, 0};
    assert_int_equal(st_sample_batch(s, &so, sq, N, want, NULL, NULL), 0);
    stc_conn *c = conn_to(&D1, NULL);
    assert_non_null(c);
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 1;
    o.want = STC_WANT_STATUS | STC_WANT_COVERAGE;
    for (int round = 0; round < 2; round++) {
        size_t n = round ? 100 : N;  /* inline (100) and worker (5000) paths */
        stc_sample_result r;
        assert_int_equal(stc_sample(c, "default", &o, q, n, &r), 0);
        assert_int_equal(r.count, n);
        assert_int_equal(r.nchan, 4);
        assert_int_equal(r.nbad, 0);
        assert_memory_equal(r.values, want, n * 4 * sizeof(float));
        assert_non_null(r.coverage);
    }
    /* SAMPLE_DIR on a set that is not a cube map */
    stc_dir_query dq = {{1, 0, 0}, {0, 0, 0}, {0, 0, 0}};
    stc_sample_result r;
    assert_int_equal(stc_sample_dir(c, "default", &o, &dq, 1, &r), STC_EUNSUPPORTED);
    /* an unknown filter is INVALID */
    o.filter = 7;
    assert_int_equal(stc_sample(c, "default", &o, q, 1, &r), STC_EINVALID);
    stc_close(c);
    free(q);
    free(sq);
    free(want);
    st_set_free(s);
}

/* Batches of split-batch (2048) queries or more are sampled in parts by the thread that has
 * them and idle workers, straight into the reply frame when the format is f32. Every form must
 * still equal the in-process sampler: inline and on a worker, split and not, f32 with and
 * without coverage and status, unorm8, and an f32 reply that starts at an odd offset of the
 * connection's output (a 1-byte PING reply queued before it: the fallback through scratch). */
static void split_batches_match_the_sampler_in_every_form(void **state)
{
    (void)state;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_default_set(&s, &e), 0);
    enum { N = 5000 };
    stc_query *q = calloc(N, sizeof *q);
    st_query *sq = calloc(N, sizeof *sq);
    float *want = calloc((size_t)N * 4, sizeof *want);
    float *wcov = calloc(N, sizeof *wcov);
    assert_true(q && sq && want && wcov);
    srand(11);
    for (int i = 0; i < N; i++) {
        q[i].face = (uint32_t)(rand() % 384);
        q[i].u = (float)rand() / (float)RAND_MAX;
        q[i].v = (float)rand() / (float)RAND_MAX;
        q[i].dudx = q[i].dvdy = 0.02f;
        memcpy(&sq[i], &q[i], sizeof sq[i]);
    }
    q[17].u = NAN;  /* a bad query inside the first part: its status and NaN values travel */
    sq[17].u = NAN;
    st_sample_opts so = {ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, 0, 0, 0, 0, 0};
    assert_int_equal(st_sample_batch(s, &so, sq, N, want, wcov, NULL), 1);
    stc_conn *c = conn_to(&D1, NULL);
    assert_non_null(c);
    /* sizes: 2047 inline unsplit, 2048 inline split, 5000 on a worker and split */
    const size_t sizes[] = {2047, 2048, 5000};
    for (int form = 0; form < 4; form++) {
        for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
            size_t n = sizes[k];
            stc_sample_opts o;
            memset(&o, 0, sizeof o);
            o.mode = 1;
            o.filter = 1;
            o.outfmt = form == 2 ? STC_OUT_UNORM8 : STC_OUT_F32;
            o.want = form == 1 ? STC_WANT_COVERAGE | STC_WANT_STATUS : 0;
            uint32_t id_ping = 0, id;
            uint8_t one = 0x5a;
            if (form == 3)
                assert_int_equal(stc_append_ping(c, &one, 1, &id_ping), 0);
            assert_int_equal(stc_append_sample(c, "default", &o, q, n, &id), 0);
            assert_int_equal(stc_flush(c), 0);
            stc_reply r;
            if (form == 3) {
                assert_int_equal(stc_get_reply(c, 10000, &r), 0);
                assert_int_equal(r.reqid, id_ping);
                assert_int_equal(r.body_len, 1);
            }
            assert_int_equal(stc_get_reply(c, 10000, &r), 0);
            assert_int_equal(r.reqid, id);
            assert_int_equal(r.status, 0);
            stc_sample_result res;
            assert_int_equal(stc_reply_sample(c, &r, &res), 0);
            assert_int_equal(res.count, n);
            assert_int_equal(res.nchan, 4);
            assert_int_equal(res.nbad, 1);
            if (form == 2) {
                const uint8_t *v = res.values;
                for (size_t i = 0; i < n * 4; i++) {
                    float w = want[i] != want[i] ? 0.0f : want[i] < 0 ? 0.0f : want[i] > 1 ? 1.0f : want[i];
                    int d = (int)v[i] - (int)lrintf(w * 255.0f);
                    assert_true(d >= -1 && d <= 1);
                }
            } else {
                /* bit for bit, NaNs included */
                assert_memory_equal(res.values, want, n * 4 * sizeof(float));
            }
            if (form == 1) {
                assert_non_null(res.coverage);
                assert_non_null(res.status);
                assert_memory_equal(res.coverage, wcov, n * sizeof(float));
                for (size_t i = 0; i < n; i++)
                    assert_int_equal(res.status[i] != 0, i == 17);
            } else {
                assert_null(res.coverage);
                assert_null(res.status);
            }
        }
    }
    /* with two CPUs or more an idle worker was woken for some of those batches */
    const stc_stat *st;
    size_t ns;
    assert_int_equal(stc_stats(c, &st, &ns), 0);
    const stc_stat *sb = stc_stat_find(st, ns, "split_batches");
    assert_non_null(sb);
    assert_non_null(stc_stat_find(st, ns, "parts_helped"));
    if (sysconf(_SC_NPROCESSORS_ONLN) >= 2)
        assert_true(sb->u > 0);
    stc_close(c);
    free(q);
    free(sq);
    free(want);
    free(wcov);
    st_set_free(s);
}

static void upload_info_fetch_delete_round_trip(void **state)
{
    (void)state;
    size_t len = 0;
    void *ptx = make_ptx(&len, 3);
    assert_non_null(ptx);
    stc_conn *c = conn_to(&D1, NULL);
    assert_non_null(c);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    uo.chunk = 100000;  /* several chunks */
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, ptx, len, "tinted.v1", &uo, &ur), 0);
    assert_int_equal(ur.nfaces, 384);
    /* a second upload of the same name without REPLACE */
    assert_int_equal(stc_upload_buffer(c, ptx, len, "tinted.v1", &uo, &ur), STC_EEXISTS);
    uo.flags = STC_UPLOAD_REPLACE;
    assert_int_equal(stc_upload_buffer(c, ptx, len, "tinted.v1", &uo, &ur), 0);
    /* the file in the data dir is byte-identical to what was sent */
    char path[1024];
    snprintf(path, sizeof path, "%s/sets/tinted.v1/manifest", D1.datadir);
    assert_int_equal(access(path, R_OK), 0);
    /* FETCH as .ptx gives the same set back: faces, adjacency and every texel identical
     * (the bytes may differ: the Ptex writer adds metadata of its own) */
    char out[600];
    snprintf(out, sizeof out, "%s/fetched.ptx", D1.dir);
    int rc = stc_fetch_file(c, "tinted.v1", STC_FETCH_PTX, out, NULL, NULL);
    assert_int_equal(rc, 0);
    st_set *a = NULL, *b = NULL;
    st_error e;
    assert_int_equal(st_ptex_read_mem(ptx, len, 0, &a, &e), 0);
    assert_int_equal(st_ptex_read_file(out, 0, &b, &e), 0);
    assert_int_equal(a->info.nfaces, b->info.nfaces);
    assert_int_equal(a->texel_bytes, b->texel_bytes);
    assert_memory_equal(a->faces, b->faces, (size_t)a->info.nfaces * sizeof *a->faces);
    assert_memory_equal(a->texels, b->texels, a->texel_bytes);
    st_set_free(a);
    st_set_free(b);
    /* a corrupt checksum is refused: raw UPLOAD_BEGIN with a wrong CRC, chunk, commit */
    stc_info info;
    assert_int_equal(stc_delete(c, "tinted.v1"), 0);
    assert_int_equal(stc_info_get(c, "tinted.v1", 0, 0, &info), STC_ENOTFOUND);
    assert_int_equal(stc_delete(c, "tinted.v1"), STC_ENOTFOUND);
    snprintf(path, sizeof path, "%s/sets/tinted.v1", D1.datadir);
    assert_int_not_equal(access(path, F_OK), 0);
    /* garbage is refused with FORMAT and leaves nothing behind */
    uo.hint = "ptx";
    assert_int_equal(stc_upload_buffer(c, "Ptex garbage that is not a file", 31, "junk", &uo, &ur),
                     STC_EFORMAT);
    assert_int_equal(stc_info_get(c, "junk", 0, 0, &info), STC_ENOTFOUND);
    stc_close(c);
    free(ptx);
}

static void compress_job_fetch_dds_and_cancel(void **state)
{
    (void)state;
    stc_conn *c = conn_to(&D1, NULL);
    assert_non_null(c);
    uint64_t job = 0;
    assert_int_equal(stc_compress(c, "default", "default-bc1", 0, STC_COMPRESS_SEAM_AWARE, &job), 0);
    assert_true(job > 0);
    stc_job js;
    assert_int_equal(stc_job_status(c, job, &js), 0);
    assert_int_equal(js.id, job);
    assert_true(js.state <= STC_JOB_DONE);
    int rc = stc_job_wait(c, job, 40000, &js);
    if (rc)
        fprintf(stderr, "job: %s %s\n", stc_strerror(rc), js.message);
    assert_int_equal(rc, 0);
    assert_int_equal(js.state, STC_JOB_DONE);
    /* the job's report: quality against the source, seams before -> after */
    print_message("# job: %s\n", js.message);
    assert_non_null(strstr(js.message, "PSNR"));
    double rms_src = 0, rms_bc1 = 0;
    const char *r = strstr(js.message, "seam RMS ");
    assert_non_null(r);
    assert_int_equal(sscanf(r, "seam RMS %lf -> %lf", &rms_src, &rms_bc1), 2);
    assert_true(rms_bc1 < rms_src);
    stc_info info;
    assert_int_equal(stc_info_get(c, "default-bc1", 0, 0, &info), 0);
    assert_int_equal(info.kind, ST_KIND_BC1);
    assert_int_equal(info.nfaces, 384);
    /* durable as a .dds in the data dir: every BC1 set has a DDS form, the default set's
     * mixed face sizes included (dds.c's set record) */
    char p[700];
    snprintf(p, sizeof p, "%s/sets/default-bc1/manifest", D1.datadir);
    assert_int_equal(access(p, R_OK), 0);
    /* the target exists now: a second job without replace is refused at once */
    assert_int_equal(stc_compress(c, "default", "default-bc1", 0, 0, &job), STC_EEXISTS);
    /* FETCH: .ptx is for per-face sets (not BC1 ones), .dds for BC1 sets */
    char out[600];
    snprintf(out, sizeof out, "%s/fetched.dds", D1.dir);
    assert_int_equal(stc_fetch_file(c, "default-bc1", STC_FETCH_PTX, out, NULL, NULL),
                     STC_EUNSUPPORTED);
    size_t ulen = 0;
    void *uptx = make_uniform_ptx(&ulen);
    assert_non_null(uptx);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, uptx, ulen, "uniform", &uo, &ur), 0);
    free(uptx);
    assert_int_equal(stc_compress(c, "uniform", "uniform-bc1", 9, STC_COMPRESS_SEAM_AWARE, &job), 0);
    assert_int_equal(stc_job_wait(c, job, 40000, &js), 0);
    snprintf(p, sizeof p, "%s/sets/uniform-bc1/manifest", D1.datadir);
    assert_int_equal(access(p, R_OK), 0);  /* durable as .dds */
    assert_int_equal(stc_fetch_file(c, "uniform-bc1", STC_FETCH_DDS, out, NULL, NULL), 0);
    FILE *f = fopen(out, "rb");
    assert_non_null(f);
    char magic[4];
    assert_int_equal(fread(magic, 1, 4, f), 4);
    fclose(f);
    assert_memory_equal(magic, "DDS ", 4);
    assert_int_equal(stc_delete(c, "uniform-bc1"), 0);
    assert_int_equal(stc_delete(c, "uniform"), 0);
    /* cancel: the job ends CANCELED (or DONE when it was quicker than the cancel) */
    assert_int_equal(stc_compress(c, "default", "bc1-canceled", 9, STC_COMPRESS_SEAM_AWARE, &job), 0);
    assert_int_equal(stc_job_cancel(c, job, &js), 0);
    int wrc = stc_job_wait(c, job, 40000, &js);
    assert_true(wrc == 0 || wrc == STC_ESERVERCANCELED);
    assert_true(js.state == STC_JOB_CANCELED || js.state == STC_JOB_DONE);
    if (js.state == STC_JOB_CANCELED)
        assert_int_equal(stc_info_get(c, "bc1-canceled", 0, 0, &info), STC_ENOTFOUND);
    assert_int_equal(stc_job_status(c, 999999, &js), STC_ENOTFOUND);
    assert_int_equal(stc_delete(c, "default-bc1"), 0);
    stc_delete(c, "bc1-canceled");
    stc_close(c);
}

/* Reads a whole file (malloc'ed) or NULL. */
static uint8_t *file_bytes(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    rewind(f);
    uint8_t *b = n > 0 ? malloc((size_t)n) : NULL;
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    *len = b ? (size_t)n : 0;
    return b;
}

/* Compresses "default" on daemon d into a .dds file (fetched) at out. */
static void compress_default_to(const st_daemon *d, const char *target, const char *out)
{
    stc_conn *c = conn_to(d, NULL);
    assert_non_null(c);
    uint64_t job = 0;
    stc_job js;
    assert_int_equal(stc_compress(c, "default", target, 5, STC_COMPRESS_SEAM_AWARE, &job), 0);
    assert_int_equal(stc_job_wait(c, job, 60000, &js), 0);
    assert_int_equal(js.state, STC_JOB_DONE);
    assert_int_equal(stc_fetch_file(c, target, STC_FETCH_DDS, out, NULL, NULL), 0);
    assert_int_equal(stc_delete(c, target), 0);
    stc_close(c);
}

/* --job-threads spreads a job's encoding over threads; the blocks do not depend on it. */
static void job_threads_give_the_same_blocks(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--job-threads", "0", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    char a[700], b[700];
    snprintf(a, sizeof a, "%s/threads-all.dds", d.dir);
    snprintf(b, sizeof b, "%s/threads-one.dds", d.dir);
    compress_default_to(&d, "jt-all", a);
    compress_default_to(&D1, "jt-one", b);
    size_t la, lb;
    uint8_t *fa = file_bytes(a, &la), *fb = file_bytes(b, &lb);
    assert_non_null(fa);
    assert_non_null(fb);
    assert_int_equal(la, lb);
    assert_memory_equal(fa, fb, la);
    free(fa);
    free(fb);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

typedef struct racer {
    const void *ptx;
    size_t len;
    int rc;
} racer;

static void *race_upload(void *arg)
{
    racer *r = arg;
    stc_conn *c = conn_to(&D1, NULL);
    if (!c) {
        r->rc = -999;
        return NULL;
    }
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    r->rc = stc_upload_buffer(c, r->ptx, r->len, "raced", &uo, &ur);
    stc_close(c);
    return NULL;
}

/* Several uploads of one new name at once without REPLACE: exactly one wins. */
static void concurrent_uploads_of_one_name_one_wins(void **state)
{
    (void)state;
    size_t len;
    void *ptx = make_ptx(&len, 4);
    assert_non_null(ptx);
    enum { K = 4 };
    racer r[K];
    pthread_t th[K];
    for (int i = 0; i < K; i++) {
        r[i].ptx = ptx;
        r[i].len = len;
        r[i].rc = -1;
        assert_int_equal(pthread_create(&th[i], NULL, race_upload, &r[i]), 0);
    }
    int ok = 0, exists = 0;
    for (int i = 0; i < K; i++) {
        pthread_join(th[i], NULL);
        ok += r[i].rc == 0;
        exists += r[i].rc == STC_EEXISTS;
    }
    assert_int_equal(ok, 1);
    assert_int_equal(exists, K - 1);
    stc_conn *c = conn_to(&D1, NULL);
    assert_int_equal(stc_delete(c, "raced"), 0);
    stc_close(c);
    free(ptx);
}

static void upload_with_wrong_crc_is_corrupt(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    uint8_t body[512], frame[1024];
    stp_buf b;
    stp_buf_init(&b);
    stp_upload_begin ub;
    memset(&ub, 0, sizeof ub);
    snprintf(ub.name, sizeof ub.name, "crcbad");
    snprintf(ub.hint, sizeof ub.hint, "ptx");
    ub.total_size = 4;
    ub.crc32c = 0x12345678;
    assert_int_equal(stp_enc_upload_begin(&b, 1, 0, &ub), 0);
    assert_int_equal(send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    rawreply r;
    assert_int_equal(read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, 0);
    uint64_t id = stp_rd64(r.body);
    stp_buf_clear(&b);
    stp_upload_chunk ch = {id, 0, 4, (const uint8_t *)"abcd"};
    stp_enc_upload_chunk(&b, 2, 0, &ch);
    stp_enc_id_req(&b, STP_OP_UPLOAD_COMMIT, 3, 0, id);
    assert_int_equal(send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    assert_int_equal(read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, 0);
    assert_int_equal(stp_rd64(r.body), 4);
    assert_int_equal(read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.reqid, 3);
    assert_int_equal(r.status, STP_S_CORRUPT);
    /* a chunk for an upload id this connection does not hold */
    stp_buf_clear(&b);
    stp_upload_chunk ch2 = {id + 1000, 0, 4, (const uint8_t *)"abcd"};
    stp_enc_upload_chunk(&b, 4, 0, &ch2);
    send_all(fd, stp_buf_head(&b), stp_buf_avail(&b));
    assert_int_equal(read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, STP_S_NOT_FOUND);
    /* a set name with a path in it */
    size_t n = stp_enc_name_req(&b, STP_OP_DELETE, 5, 0, "a") == 0 ? 0 : 0;
    (void)n;
    uint8_t nb[16] = {5, 0, '.', '.', '/', 'x', 'y'};
    size_t fl = put_frame(frame, "STX1", 1, STP_OP_DELETE, 0, 6, nb, 7, 7);
    send_all(fd, frame, fl);
    assert_int_equal(read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.reqid, 6);
    assert_true(r.status == STP_S_PERM || r.status == STP_S_BAD_REQUEST);
    stp_buf_free(&b);
    (void)body;
    close(fd);
}

static uint64_t stat_of(const st_daemon *d, const char *key)
{
    stc_conn *c = conn_to(d, NULL);
    if (!c)
        return UINT64_MAX;
    const stc_stat *st;
    size_t n;
    uint64_t v = UINT64_MAX;
    if (stc_stats(c, &st, &n) == 0 && stc_stat_find(st, n, key))
        v = stc_stat_find(st, n, key)->u;
    stc_close(c);
    return v;
}

/* Begins an upload of `len` bytes on a raw socket and sends its first `part` bytes; returns
 * the socket (the caller closes it to drop the connection) and the upload id. */
static int raw_partial_upload(const st_daemon *d, const char *name, const uint8_t *data,
                              size_t len, size_t part, uint64_t *id)
{
    int fd = st_daemon_connect(d);
    assert_true(fd >= 0);
    stp_buf b;
    stp_buf_init(&b);
    stp_upload_begin ub;
    memset(&ub, 0, sizeof ub);
    snprintf(ub.name, sizeof ub.name, "%s", name);
    snprintf(ub.hint, sizeof ub.hint, "ptx");
    ub.total_size = len;
    ub.crc32c = stp_crc32c(0, data, len);
    assert_int_equal(stp_enc_upload_begin(&b, 1, 0, &ub), 0);
    assert_int_equal(send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    rawreply r;
    assert_int_equal(read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, 0);
    *id = stp_rd64(r.body);
    assert_int_equal(stp_rd64(r.body + 8), 0);
    for (size_t off = 0, k = 2; off < part; k++) {
        size_t n = part - off < 65536 ? part - off : 65536;
        stp_buf_clear(&b);
        stp_upload_chunk ch = {*id, off, (uint32_t)n, data + off};
        stp_enc_upload_chunk(&b, (uint32_t)k, 0, &ch);
        assert_int_equal(send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
        assert_int_equal(read_reply(fd, &r, 5000), 0);
        assert_int_equal(r.status, 0);
        off += n;
        assert_int_equal(stp_rd64(r.body), off);
    }
    stp_buf_free(&b);
    return fd;
}

/* Upload with RESUME, retrying while the server has not yet seen the old connection close. */
static int upload_resume(stc_conn *c, const void *data, size_t len, const char *name,
                         stc_upload_result *ur)
{
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    uo.flags = STC_UPLOAD_RESUME;
    int rc = STC_EBUSY;
    for (int i = 0; i < 100 && rc == STC_EBUSY; i++) {
        rc = stc_upload_buffer(c, data, len, name, &uo, ur);
        if (rc == STC_EBUSY)
            usleep(20000);
    }
    return rc;
}

/* A dropped connection leaves its upload kept; UPLOAD_BEGIN with RESUME on a new connection
 * continues from the bytes the server has, and the set is whole (INFO matches, CRC checked). */
static void dropped_upload_resumes_on_a_new_connection(void **state)
{
    (void)state;
    size_t len;
    uint8_t *ptx = make_ptx(&len, 3);
    assert_non_null(ptx);
    assert_true(len > 3 * 65536);
    uint64_t id;
    size_t part = 2 * 65536 + 1000;
    int fd = raw_partial_upload(&D1, "resumed", ptx, len, part, &id);
    uint64_t before = stat_of(&D1, "upload_bytes");
    close(fd);
    stc_conn *c = conn_to(&D1, NULL);
    assert_non_null(c);
    assert_true(stc_server_info(c)->caps & STC_CAP_UPLOAD_RESUME);
    stc_upload_result ur;
    assert_int_equal(upload_resume(c, ptx, len, "resumed", &ur), 0);
    assert_int_equal(ur.resumed_from, part);
    assert_int_equal(stat_of(&D1, "upload_bytes") - before, len - part); /* only the rest sent */
    assert_true(stat_of(&D1, "uploads_resumed") >= 1);
    stc_info inf;
    assert_int_equal(stc_info_get(c, "resumed", 0, 0, &inf), 0);
    assert_int_equal(inf.nfaces, 384);
    /* a different file under another name: nothing to resume, a fresh upload */
    fd = raw_partial_upload(&D1, "resumed2", ptx, len, 65536, &id);
    close(fd);
    /* other content, so another CRC32C: the kept upload is not taken; the fresh upload of the
     * damaged file fails to import or not, either way without resuming */
    uint64_t resumed = stat_of(&D1, "uploads_resumed");
    ptx[len / 2] ^= 0x40;
    int rc = upload_resume(c, ptx, len, "resumed2", &ur);
    if (rc == 0)
        assert_int_equal(ur.resumed_from, 0);
    assert_int_equal(stat_of(&D1, "uploads_resumed"), resumed);
    ptx[len / 2] ^= 0x40;
    if (rc == 0) {
        assert_int_equal(stc_delete(c, "resumed2"), 0);
    }
    assert_int_equal(upload_resume(c, ptx, len, "resumed2", &ur), 0);
    assert_int_equal(ur.resumed_from, 65536);
    /* the connection broke while COMMIT ran (its reply lost): RESUME finds the upload done,
     * COMMIT repeats the reply, and no byte is sent again */
    before = stat_of(&D1, "upload_bytes");
    assert_int_equal(upload_resume(c, ptx, len, "resumed2", &ur), 0);
    assert_int_equal(ur.resumed_from, len);
    assert_string_equal(ur.name, "resumed2");
    assert_int_equal(ur.nfaces, 384);
    assert_int_equal(stat_of(&D1, "upload_bytes"), before);
    /* once the set is deleted that record no longer counts: a fresh upload */
    assert_int_equal(stc_delete(c, "resumed2"), 0);
    assert_int_equal(upload_resume(c, ptx, len, "resumed2", &ur), 0);
    assert_int_equal(ur.resumed_from, 0);
    stc_close(c);
    free(ptx);
}

/* Kept uploads go after upload-keep seconds; with upload-keep 0 nothing is kept and the
 * server does not offer RESUME. */
static void kept_uploads_expire_and_can_be_turned_off(void **state)
{
    (void)state;
    size_t len;
    uint8_t *ptx = make_ptx(&len, 4);
    assert_non_null(ptx);
    st_daemon d;
    const char *extra[] = {"--upload-keep", "1", "--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    uint64_t id;
    int fd = raw_partial_upload(&d, "late", ptx, len, 65536, &id);
    close(fd);
    int64_t t0 = now_ms();
    while (stat_of(&d, "uploads_expired") == 0 && now_ms() - t0 < 5000)
        usleep(100000);
    assert_int_equal(stat_of(&d, "uploads_expired"), 1);
    assert_true(now_ms() - t0 >= 900);
    stc_conn *c = conn_to(&d, NULL);
    assert_non_null(c);
    stc_upload_result ur;
    assert_int_equal(upload_resume(c, ptx, len, "late", &ur), 0);
    assert_int_equal(ur.resumed_from, 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);

    const char *off[] = {"--upload-keep", "0", "--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, off), 0);
    fd = raw_partial_upload(&d, "gone", ptx, len, 65536, &id);
    close(fd);
    c = conn_to(&d, NULL);
    assert_non_null(c);
    assert_false(stc_server_info(c)->caps & STC_CAP_UPLOAD_RESUME);
    assert_int_equal(upload_resume(c, ptx, len, "gone", &ur), 0);
    assert_int_equal(ur.resumed_from, 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
    free(ptx);
}

static void pipelined_requests_come_back_in_order(void **state)
{
    (void)state;
    stc_conn *c = conn_to(&D1, NULL);
    assert_non_null(c);
    enum { N = 2000 };
    uint32_t ids[N];
    stc_query q = {0, 0.5f, 0.5f, 0, 0, 0, 0};
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 1;
    for (int i = 0; i < N; i++) {
        int rc;
        if (i % 3 == 0)
            rc = stc_append_sample(c, "default", &o, &q, 1, &ids[i]);
        else if (i % 3 == 1)
            rc = stc_append_ping(c, &i, sizeof i, &ids[i]);
        else
            rc = stc_append_info(c, "default", &ids[i]);
        assert_int_equal(rc, 0);
    }
    assert_int_equal(stc_flush(c), 0);
    for (int i = 0; i < N; i++) {
        stc_reply r;
        assert_int_equal(stc_get_reply(c, 10000, &r), 0);
        assert_int_equal(r.reqid, ids[i]);
        assert_int_equal(r.status, 0);
        if (i % 3 == 1) {
            assert_int_equal(r.body_len, sizeof i);
            assert_memory_equal(r.body, &i, sizeof i);
        }
    }
    /* the server batched: far fewer writes than replies */
    const stc_stat *st;
    size_t n;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    const stc_stat *w = stc_stat_find(st, n, "writes");
    const stc_stat *rq = stc_stat_find(st, n, "requests");
    assert_non_null(w);
    assert_non_null(rq);
    assert_true(w->u * 4 < rq->u);
    stc_close(c);
}

/* The malformed-frame table: each row is sent on its own connection, followed by a PING; the
 * expected status comes back (or the connection is closed, for a bad magic) and a separate
 * connection is served normally afterwards. */
static void malformed_frames_get_their_status(void **state)
{
    (void)state;
    float good[7] = {0, 0.5f, 0.5f, 0, 0, 0, 0};
    float nanq[14] = {0, NAN, 0.5f, 0, 0, 0, 0, 1, 0.25f, 0.25f, 0, 0, 0, 0};
    struct row {
        const char *what;
        int kind;          /* 0 frame with body, 1 bad magic, 2 truncated header, 3 huge */
        unsigned version, op, flags;
        int body;          /* 0 none, 1 lying sample count, 2 zero batch, 3 NaN queries,
                              4 trailing byte, 5 one good query */
        int status;        /* expected; -1 = connection closed */
        uint32_t nbad;     /* SAMPLE rows: expected nbad */
    } rows[] = {
        {"bad magic", 1, 1, STP_OP_PING, 0, 0, -1, 0},
        {"bad version", 0, 7, STP_OP_PING, 0, 0, STP_S_BAD_VERSION, 0},
        {"unknown opcode", 0, 1, 0x5e, 0, 0, STP_S_UNKNOWN_OPCODE, 0},
        {"reply flag in a request", 0, 1, STP_OP_PING, STP_F_REPLY, 0, STP_S_BAD_REQUEST, 0},
        {"truncated header then more", 2, 1, STP_OP_PING, 0, 0, STP_S_OK, 0},
        {"body over max-frame", 3, 1, STP_OP_PING, 0, 0, STP_S_TOO_LARGE, 0},
        {"INFO body over its cap", 3, 1, STP_OP_INFO, 0, 0, STP_S_TOO_LARGE, 0},
        {"lying count in SAMPLE", 0, 1, STP_OP_SAMPLE, 0, 1, STP_S_BAD_REQUEST, 0},
        {"zero-length batch", 0, 1, STP_OP_SAMPLE, 0, 2, STP_S_OK, 0},
        {"NaN query", 0, 1, STP_OP_SAMPLE, 0, 3, STP_S_OK, 1},
        {"trailing byte in SAMPLE", 0, 1, STP_OP_SAMPLE, 0, 4, STP_S_BAD_REQUEST, 0},
        {"one good query", 0, 1, STP_OP_SAMPLE, 0, 5, STP_S_OK, 0},
        {"empty STATS body with bytes", 0, 1, STP_OP_STATS, 0, 5, STP_S_BAD_REQUEST, 0},
    };
    uint8_t *frame = malloc((1 << 16) + 64), body[4096];
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        const struct row *w = &rows[i];
        int fd = st_daemon_connect(&D1);
        assert_true(fd >= 0);
        size_t bl = 0;
        uint32_t claimed;
        switch (w->body) {
        case 1: bl = sample_body(body, "default", 3, good, 1); break;
        case 2: bl = sample_body(body, "default", 0, good, 0); break;
        case 3: bl = sample_body(body, "default", 2, nanq, 2); break;
        case 4: bl = sample_body(body, "default", 1, good, 1); body[bl++] = 0; break;
        case 5: bl = sample_body(body, "default", 1, good, 1); break;
        default: bl = 0; break;
        }
        claimed = (uint32_t)bl;
        size_t fl;
        if (w->kind == 1) {
            fl = put_frame(frame, "STY1", 1, w->op, 0, 100 + (uint32_t)i, NULL, 0, 0);
            assert_int_equal(send_all(fd, frame, fl), 0);
        } else if (w->kind == 2) {
            fl = put_frame(frame, "STX1", 1, w->op, 0, 100 + (uint32_t)i, "xy", 2, 2);
            assert_int_equal(send_all(fd, frame, 10), 0);
            struct timespec ts = {0, 100 * 1000000L};
            nanosleep(&ts, NULL);
            assert_int_equal(send_all(fd, frame + 10, fl - 10), 0);
        } else if (w->kind == 3) {
            /* claims a huge body and sends 64 KiB of it: the server must skip, not store */
            uint32_t huge = w->op == STP_OP_PING ? (100u << 20) : 65536;
            fl = put_frame(frame, "STX1", 1, w->op, 0, 100 + (uint32_t)i, NULL, 0, huge);
            memset(frame + fl, 0xAB, 65536);
            assert_int_equal(send_all(fd, frame, fl + 65536), 0);
            if (w->op == STP_OP_PING) {
                /* the rest of the 100 MiB would be skipped too; close instead of sending it */
            }
        } else {
            fl = put_frame(frame, "STX1", w->version, w->op, w->flags, 100 + (uint32_t)i, body,
                           (uint32_t)bl, claimed);
            assert_int_equal(send_all(fd, frame, fl), 0);
        }
        rawreply r;
        if (w->status < 0) {
            assert_true(peer_closed(fd, 5000));
        } else {
            int rc = read_reply(fd, &r, 5000);
            if (rc != 0)
                fprintf(stderr, "row '%s': no reply\n", w->what);
            assert_int_equal(rc, 0);
            if ((int)r.status != w->status)
                fprintf(stderr, "row '%s': status %u, want %d (%.*s)\n", w->what, r.status,
                        w->status, (int)r.len, (const char *)r.body);
            assert_int_equal(r.status, w->status);
            assert_int_equal(r.reqid, 100 + (uint32_t)i);
            assert_true(r.flags & STP_F_REPLY);
            if (w->op == STP_OP_SAMPLE && w->status == STP_S_OK) {
                assert_int_equal(stp_rd32(r.body + 8), w->nbad);
                if (w->body == 3) {  /* the NaN query: status NONFINITE, the other OK */
                    uint32_t cnt = stp_rd32(r.body);
                    assert_int_equal(cnt, 2);
                    const uint8_t *stat = r.body + 12 + 2 * 4 * 4;
                    assert_int_equal(stat[0], ST_Q_NONFINITE);
                    assert_int_equal(stat[1], ST_Q_OK);
                }
            }
            /* the same connection still serves (except after a skipped 100 MiB body) */
            if (!(w->kind == 3 && w->op == STP_OP_PING)) {
                if (w->kind == 3) {
                    /* INFO claimed 64 KiB, all of it sent: it was skipped */
                }
                fl = put_frame(frame, "STX1", 1, STP_OP_PING, 0, 999, "ok", 2, 2);
                assert_int_equal(send_all(fd, frame, fl), 0);
                assert_int_equal(read_reply(fd, &r, 5000), 0);
                assert_int_equal(r.reqid, 999);
                assert_int_equal(r.status, 0);
            }
        }
        close(fd);
        /* another connection is served */
        stc_conn *c = conn_to(&D1, NULL);
        assert_non_null(c);
        assert_int_equal(stc_ping(c), 0);
        stc_close(c);
    }
    free(frame);
}

/* ---- group 2: limits ------------------------------------------------------------------------- */

static void max_conns_rejects_with_busy(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--max-conns", "3", "--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    /* the fixture's readiness probe used one connection; let it close */
    struct timespec ts = {0, 200 * 1000000L};
    nanosleep(&ts, NULL);
    stc_conn *c[3];
    for (int i = 0; i < 3; i++) {
        c[i] = conn_to(&d, NULL);
        assert_non_null(c[i]);
    }
    int fd = st_daemon_connect(&d);
    assert_true(fd >= 0);
    rawreply r;
    assert_int_equal(read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, STP_S_BUSY);
    assert_true(peer_closed(fd, 5000));
    close(fd);
    stc_close(c[0]);
    nanosleep(&ts, NULL);
    stc_conn *again = conn_to(&d, NULL);
    assert_non_null(again);
    const stc_stat *st;
    size_t n;
    assert_int_equal(stc_stats(again, &st, &n), 0);
    assert_true(stc_stat_find(st, n, "conns_rejected")->u >= 1);
    stc_close(again);
    stc_close(c[1]);
    stc_close(c[2]);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

static void idle_connections_are_closed(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--idle-timeout", "1", "--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    int fd = st_daemon_connect(&d);
    assert_true(fd >= 0);
    int64_t t0 = now_ms();
    assert_true(peer_closed(fd, 5000));
    int64_t dt = now_ms() - t0;
    assert_true(dt >= 900 && dt < 4000);
    close(fd);
    stc_conn *c = conn_to(&d, NULL);
    assert_non_null(c);
    const stc_stat *st;
    size_t n;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    assert_true(stc_stat_find(st, n, "conns_idle_closed")->u >= 1);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

static void upload_and_frame_caps_hold(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--max-upload", "100K", "--max-frame", "64K", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    stc_conn *c = conn_to(&d, NULL);
    assert_non_null(c);
    assert_int_equal(stc_server_info(c)->max_body, 65536);
    size_t len;
    void *ptx = make_ptx(&len, 1);
    assert_non_null(ptx);
    assert_true(len > 100 * 1024);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, ptx, len, "big", &uo, &ur), STC_ETOOLARGE);
    free(ptx);
    /* a SAMPLE batch over 64 KiB is split by the client: it still works */
    enum { N = 4000 };
    stc_query *q = calloc(N, sizeof *q);
    for (int i = 0; i < N; i++) {
        q[i].face = (uint32_t)i % 384;
        q[i].u = q[i].v = 0.5f;
    }
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 1;
    stc_sample_result r;
    int rc = stc_sample(c, "default", &o, q, N, &r);
    assert_true(rc == 0 || rc == STC_ETOOLARGE);
    free(q);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}


/* A client that pipelines without reading: the server stops reading it once its unsent
 * replies pass conn-out-cap, holds bounded memory, and answers everything once the client
 * reads. */
static void unread_replies_pause_reading(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--conn-out-cap", "256K", "--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    int fd = st_daemon_connect(&d);
    assert_true(fd >= 0);
    int small = 64 * 1024;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    enum { PAY = 1000, MAXF = 200000 };
    uint8_t frame[24 + PAY];
    memset(frame + 24, 0x5C, PAY);
    uint32_t sent = 0;
    size_t partial = 0;  /* bytes of frame `sent` already out */
    /* send without reading until the server reports a pause (it must: nothing is read) */
    uint64_t pauses = 0;
    int64_t end0 = now_ms() + 20000, next_check = 0;
    while (sent < MAXF && now_ms() < end0) {
        put_frame(frame, "STX1", 1, STP_OP_PING, 0, sent + 1, NULL, 0, PAY);
        ssize_t w = send(fd, frame + partial, sizeof frame - partial, MSG_DONTWAIT | MSG_NOSIGNAL);
        if (w > 0) {
            partial += (size_t)w;
            if (partial == sizeof frame) {
                partial = 0;
                sent++;
            }
            continue;
        }
        if (now_ms() >= next_check) {
            pauses = stat_of(&d, "backpressure_pauses");
            if (pauses >= 1 && pauses != UINT64_MAX)
                break;
            next_check = now_ms() + 50;
        }
        struct timespec ts = {0, 5 * 1000000L};
        nanosleep(&ts, NULL);
    }
    assert_true(sent < MAXF);
    assert_true(pauses >= 1 && pauses != UINT64_MAX);
    uint64_t mem = stat_of(&d, "buffer_memory");
    assert_true(mem < (8u << 20));
    /* now read everything, finishing the partial frame as the server reads again */
    uint32_t total = sent + (partial ? 1 : 0), got = 0;
    static uint8_t rbuf[1 << 16];
    size_t have = 0;
    int64_t end = now_ms() + 30000;
    while (got < total && now_ms() < end) {
        struct pollfd p = {fd, (short)(POLLIN | (partial ? POLLOUT : 0)), 0};
        if (poll(&p, 1, 1000) <= 0)
            continue;
        if (partial && (p.revents & POLLOUT)) {
            ssize_t w = send(fd, frame + partial, sizeof frame - partial, MSG_DONTWAIT | MSG_NOSIGNAL);
            if (w > 0) {
                partial += (size_t)w;
                if (partial == sizeof frame)
                    partial = 0;
            }
        }
        if (p.revents & POLLIN) {
            ssize_t r = recv(fd, rbuf + have, sizeof rbuf - have, 0);
            assert_true(r > 0);
            have += (size_t)r;
            size_t off = 0;
            while (have - off >= 24 && have - off >= 24 + (size_t)stp_rd32(rbuf + off + 16)) {
                assert_int_equal(stp_rd32(rbuf + off + 8), got + 1);  /* in order */
                assert_int_equal(stp_rd16(rbuf + off + 12), 0);
                assert_int_equal(stp_rd32(rbuf + off + 16), PAY);
                off += 24 + PAY;
                got++;
            }
            memmove(rbuf, rbuf + off, have - off);
            have -= off;
        }
    }
    assert_int_equal(got, total);
    close(fd);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

static long rss_kb(pid_t pid)
{
    char p[64], line[256];
    snprintf(p, sizeof p, "/proc/%d/status", (int)pid);
    FILE *f = fopen(p, "r");
    long kb = -1;
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, "VmRSS:", 6))
            kb = atol(line + 6);
    if (f)
        fclose(f);
    return kb;
}

/* Idle connections cost little: 2000 connections that each sent one PING add well under
 * 2 KiB of resident memory apiece to the daemon. */
static void idle_connections_cost_little_memory(void **state)
{
    (void)state;
    struct rlimit rl;
    getrlimit(RLIMIT_NOFILE, &rl);
    enum { N = 2000 };
#if defined(__SANITIZE_ADDRESS__)
    skip();  /* AddressSanitizer's allocator (redzones, quarantine) is not what is measured */
#endif
    if (rl.rlim_max != RLIM_INFINITY && rl.rlim_max < N + 64) {
        skip();
    }
    rl.rlim_cur = rl.rlim_max;
    setrlimit(RLIMIT_NOFILE, &rl);
    st_daemon d;
    const char *extra[] = {"--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    struct timespec ts = {0, 300 * 1000000L};
    nanosleep(&ts, NULL);
    long before = rss_kb(d.pid);
    static int fds[N];
    uint8_t frame[64];
    size_t fl = put_frame(frame, "STX1", 1, STP_OP_PING, 0, 1, "x", 1, 1);
    for (int i = 0; i < N; i++) {
        fds[i] = st_daemon_connect(&d);
        assert_true(fds[i] >= 0);
        assert_int_equal(send_all(fds[i], frame, fl), 0);
    }
    for (int i = 0; i < N; i++) {
        rawreply r;
        assert_int_equal(read_reply(fds[i], &r, 5000), 0);
    }
    nanosleep(&ts, NULL);
    long after = rss_kb(d.pid);
    assert_true(before > 0 && after > 0);
    print_message("# %d idle connections: daemon RSS %ld -> %ld KiB (%.0f bytes each)\n", N,
                  before, after, (double)(after - before) * 1024.0 / N);
    assert_true((after - before) * 1024 < 2048L * N);
    assert_int_equal(stat_of(&d, "conns_current"), N + 1);
    for (int i = 0; i < N; i++)
        close(fds[i]);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

/* ---- group 3: token, reload, restart, graceful stop --------------------------------------------- */

static void token_guards_mutations_only(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--token", "s3cret", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    size_t len;
    void *ptx = make_ptx(&len, 2);
    assert_non_null(ptx);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    stc_conn *anon = conn_to(&d, NULL);
    stc_conn *wrong = conn_to(&d, "guess");
    stc_conn *ok = conn_to(&d, "s3cret");
    assert_non_null(anon);
    assert_non_null(wrong);
    assert_non_null(ok);
    assert_true(stc_server_info(anon)->caps & STP_CAP_AUTH);
    assert_false(stc_server_info(wrong)->authenticated);
    assert_true(stc_server_info(ok)->authenticated);
    assert_int_equal(stc_ping(anon), 0);
    stc_info info;
    assert_int_equal(stc_info_get(anon, "default", 0, 0, &info), 0);
    assert_int_equal(stc_upload_buffer(anon, ptx, len, "t1", &uo, &ur), STC_EPERM);
    assert_int_equal(stc_upload_buffer(wrong, ptx, len, "t1", &uo, &ur), STC_EPERM);
    assert_int_equal(stc_delete(anon, "default"), STC_EPERM);
    assert_int_equal(stc_upload_buffer(ok, ptx, len, "t1", &uo, &ur), 0);
    assert_int_equal(stc_delete(ok, "t1"), 0);
    stc_close(anon);
    stc_close(wrong);
    stc_close(ok);
    free(ptx);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
}

static void sighup_reloads_limits_and_token(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    char conf[400];
    snprintf(conf, sizeof conf, "%s/seamtexd.conf", d.dir);
    FILE *f = fopen(conf, "w");
    assert_non_null(f);
    fprintf(f, "# test config\nmax-conns = 100\nlog-level = info\n");
    fclose(f);
    const char *extra[] = {"--config", conf, "--no-default-set", NULL};
    assert_int_equal(st_daemon_start(&d, extra), 0);
    stc_conn *c = conn_to(&d, NULL);
    assert_non_null(c);
    const stc_stat *st;
    size_t n;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    assert_int_equal(stc_stat_find(st, n, "max_conns")->u, 100);
    f = fopen(conf, "w");
    fprintf(f, "max-conns = 77\ntoken = newtoken\nlog-level = debug\n");
    fclose(f);
    assert_int_equal(st_daemon_signal(&d, SIGHUP), 0);
    int64_t end = now_ms() + 5000;
    uint64_t v = 0;
    while (now_ms() < end) {
        assert_int_equal(stc_stats(c, &st, &n), 0);
        v = stc_stat_find(st, n, "max_conns")->u;
        if (v == 77)
            break;
        struct timespec ts = {0, 20 * 1000000L};
        nanosleep(&ts, NULL);
    }
    assert_int_equal(v, 77);
    /* the token now applies: this connection never sent it */
    assert_int_equal(stc_delete(c, "x"), STC_EPERM);
    stc_close(c);
    /* a broken config is refused and logged; the daemon keeps running */
    f = fopen(conf, "w");
    fprintf(f, "max-conns = lots\n");
    fclose(f);
    assert_int_equal(st_daemon_signal(&d, SIGHUP), 0);
    struct timespec ts = {0, 200 * 1000000L};
    nanosleep(&ts, NULL);
    c = conn_to(&d, NULL);
    assert_non_null(c);
    assert_int_equal(stc_ping(c), 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    /* the log names what changed */
    f = fopen(d.log, "r");
    char line[1024];
    int saw = 0, refused = 0;
    while (f && fgets(line, sizeof line, f)) {
        if (strstr(line, "max-conns: 100 -> 77") && strstr(line, "token: (changed)"))
            saw = 1;
        if (strstr(line, "not reloaded"))
            refused = 1;
    }
    if (f)
        fclose(f);
    assert_true(saw);
    assert_true(refused);
    st_daemon_cleanup(&d);
}

static void restart_loads_sets_and_cleans_leftovers(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    size_t len;
    void *ptx = make_ptx(&len, 5);
    assert_non_null(ptx);
    stc_conn *c = conn_to(&d, NULL);
    assert_non_null(c);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, ptx, len, "keep-me", &uo, &ur), 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    /* plant what a crash leaves: a temp file, a set dir without manifest, an orphan source,
     * and a set whose source was damaged */
    char p[700];
    snprintf(p, sizeof p, "%s/tmp/123.part", d.datadir);
    FILE *f = fopen(p, "w");
    fputs("half", f);
    fclose(f);
    snprintf(p, sizeof p, "%s/sets/halfway", d.datadir);
    assert_int_equal(mkdir(p, 0700), 0);
    snprintf(p, sizeof p, "%s/sets/halfway/source-1.ptx", d.datadir);
    f = fopen(p, "w");
    fputs("half", f);
    fclose(f);
    snprintf(p, sizeof p, "%s/sets/keep-me/source-orphan.ptx", d.datadir);
    f = fopen(p, "w");
    fputs("orphan", f);
    fclose(f);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    c = conn_to(&d, NULL);
    assert_non_null(c);
    const stc_set_entry *sets;
    size_t n;
    assert_int_equal(stc_list(c, &sets, &n), 0);
    assert_int_equal(n, 1);
    assert_string_equal(sets[0].name, "keep-me");
    assert_int_equal(sets[0].nfaces, 384);
    stc_close(c);
    assert_int_not_equal(access(p, F_OK), 0);
    snprintf(p, sizeof p, "%s/sets/halfway", d.datadir);
    assert_int_not_equal(access(p, F_OK), 0);
    snprintf(p, sizeof p, "%s/tmp/123.part", d.datadir);
    assert_int_not_equal(access(p, F_OK), 0);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    /* damage the committed source: the set is moved to broken/, not loaded, not lost */
    char man[700];
    snprintf(man, sizeof man, "%s/sets/keep-me/manifest", d.datadir);
    f = fopen(man, "r");
    char line[256], src[256] = "";
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, "source ", 7)) {
            snprintf(src, sizeof src, "%s", line + 7);
            src[strcspn(src, "\n")] = 0;
        }
    fclose(f);
    snprintf(p, sizeof p, "%s/sets/keep-me/%s", d.datadir, src);
    f = fopen(p, "r+b");
    assert_non_null(f);
    fseek(f, 100, SEEK_SET);
    fputc(0x5A, f);
    fclose(f);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    c = conn_to(&d, NULL);
    assert_int_equal(stc_list(c, &sets, &n), 0);
    assert_int_equal(n, 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    free(ptx);
    st_daemon_cleanup(&d);
}

static void sigterm_finishes_requests_in_flight(void **state)
{
    (void)state;
    st_daemon d;
    const char *extra[] = {"--heavy-batch", "1000", "--workers", "1", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    stc_conn *c = conn_to(&d, NULL);
    assert_non_null(c);
    enum { N = 200000, K = 4 };
    stc_query *q = calloc(N, sizeof *q);
    for (int i = 0; i < N; i++) {
        q[i].face = (uint32_t)i % 384;
        q[i].u = (float)(i % 1000) / 1000.0f;
        q[i].v = 0.5f;
        q[i].dudx = q[i].dvdy = 0.05f;
    }
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 2;
    uint32_t ids[K];
    for (int k = 0; k < K; k++)
        assert_int_equal(stc_append_sample(c, "default", &o, q, N, &ids[k]), 0);
    assert_int_equal(stc_flush(c), 0);
    struct timespec ts = {0, 30 * 1000000L};
    nanosleep(&ts, NULL);
    assert_int_equal(st_daemon_signal(&d, SIGTERM), 0);
    for (int k = 0; k < K; k++) {
        stc_reply r;
        assert_int_equal(stc_get_reply(c, 20000, &r), 0);
        assert_int_equal(r.reqid, ids[k]);
        assert_int_equal(r.status, 0);
        stc_sample_result res;
        assert_int_equal(stc_reply_sample(c, &r, &res), 0);
        assert_int_equal(res.count, N);
    }
    stc_close(c);
    free(q);
    /* exits 0 by itself */
    int rc = st_daemon_stop(&d, 15000);
    assert_true(rc == 0 || rc == -1);  /* -1: already gone, reaped by stop */
    assert_int_equal(d.exit_status, 0);
    st_daemon_cleanup(&d);
}

static void help_teaches_every_flag(void **state)
{
    (void)state;
    /* --help and a bad flag, through the fixture's spawn (never fork here) */
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    const char *bad[] = {"--max-conns", "many", NULL};
    assert_int_not_equal(st_daemon_start(&d, bad), 0);
    assert_int_equal(d.exit_status, 2);
    FILE *f = fopen(d.log, "r");
    char line[512];
    int named = 0;
    while (f && fgets(line, sizeof line, f))
        if (strstr(line, "max-conns") && strstr(line, "many"))
            named = 1;
    if (f)
        fclose(f);
    assert_true(named);
    st_daemon_cleanup(&d);
}

int main(void)
{
    const struct CMUnitTest basic[] = {
        cmocka_unit_test(hello_reports_limits_and_caps),
        cmocka_unit_test(ping_list_info_stats_answer),
        cmocka_unit_test(sample_matches_in_process_sampler),
        cmocka_unit_test(split_batches_match_the_sampler_in_every_form),
        cmocka_unit_test(upload_info_fetch_delete_round_trip),
        cmocka_unit_test(compress_job_fetch_dds_and_cancel),
        cmocka_unit_test(job_threads_give_the_same_blocks),
        cmocka_unit_test(upload_with_wrong_crc_is_corrupt),
        cmocka_unit_test(dropped_upload_resumes_on_a_new_connection),
        cmocka_unit_test(kept_uploads_expire_and_can_be_turned_off),
        cmocka_unit_test(concurrent_uploads_of_one_name_one_wins),
        cmocka_unit_test(pipelined_requests_come_back_in_order),
        cmocka_unit_test(malformed_frames_get_their_status),
    };
    const struct CMUnitTest own[] = {
        cmocka_unit_test(max_conns_rejects_with_busy),
        cmocka_unit_test(idle_connections_are_closed),
        cmocka_unit_test(upload_and_frame_caps_hold),
        cmocka_unit_test(unread_replies_pause_reading),
        cmocka_unit_test(idle_connections_cost_little_memory),
        cmocka_unit_test(token_guards_mutations_only),
        cmocka_unit_test(sighup_reloads_limits_and_token),
        cmocka_unit_test(restart_loads_sets_and_cleans_leftovers),
        cmocka_unit_test(sigterm_finishes_requests_in_flight),
        cmocka_unit_test(help_teaches_every_flag),
    };
    int fails = cmocka_run_group_tests_name("server_requests", basic, setup_default,
                                            teardown_default);
    fails += cmocka_run_group_tests_name("server_limits", own, NULL, NULL);
    return fails;
}
