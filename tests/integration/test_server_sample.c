/* tests/integration/test_server_sample.c - seamtexd's read requests through libseamtex:
 * HELLO, PING, LIST, INFO, STATS, SAMPLE equal to the in-process sampler (inline, on a worker,
 * split in parts, in every output form, two connections of split batches at once) and
 * pipelined requests answered in order.
 *
 * One daemon with defaults for the group (tests/common/daemon_fixture.h) on 127.0.0.1 port 0;
 * nothing here needs SEAMTEX_DATA.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "defaultset.h"
#include "proto.h"
#include "sample.h"

/* the group's daemon: defaults, --heavy-batch 2048 (set in main) */
#define D1 ST_GROUP

/* ---- tests ---------------------------------------------------------------------------------- */

static void hello_reports_limits_and_caps(void **state)
{
    (void)state;
    stc_conn *c = st_daemon_client(&D1, NULL);
    assert_non_null(c);
    const stc_server *s = stc_server_info(c);
    assert_int_equal(s->version, 1);
    assert_true(s->caps & STP_CAP_PIPELINE);
    assert_true(s->caps & STP_CAP_LERP);
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
    stc_conn *c = st_daemon_client(&D1, NULL);
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
    st_sample_opts so = {ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, 0, 0, 0, 0, 0, 0};
    assert_int_equal(st_sample_batch(s, &so, sq, N, want, NULL, NULL), 0);
    stc_conn *c = st_daemon_client(&D1, NULL);
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
    st_sample_opts so = {ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, 0, 0, 0, 0, 0, 0};
    assert_int_equal(st_sample_batch(s, &so, sq, N, want, wcov, NULL), 1);
    stc_conn *c = st_daemon_client(&D1, NULL);
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

/* Two connections (two I/O threads) each pipelining split-size batches at once: both I/O
 * threads sample side by side, helpers are woken only onto a CPU neither keeps and leave a
 * batch when another starts (workers.c). Whatever the split, every reply is the in-process
 * sampler's, bit for bit, for that connection's own queries, in request order. */
static void two_connections_of_split_batches_answer_exactly_in_order(void **state)
{
    (void)state;
    st_set *s = NULL;
    st_error e;
    assert_int_equal(st_default_set(&s, &e), 0);
    enum { N = 2048, K = 8, C = 2 };   /* 2048: inline (--heavy-batch 2048) and split */
    stc_query *q[C][K];
    float *want[C][K];
    st_sample_opts so = {ST_MODE_TRAVERSE, ST_FILTER_BILINEAR, 0, 0, 0, 0, 0, 0};
    srand(23);
    for (int c = 0; c < C; c++)
        for (int k = 0; k < K; k++) {
            q[c][k] = calloc(N, sizeof(stc_query));
            st_query *sq = calloc(N, sizeof *sq);
            want[c][k] = calloc((size_t)N * 4, sizeof(float));
            assert_true(q[c][k] && sq && want[c][k]);
            for (int i = 0; i < N; i++) {
                q[c][k][i].face = (uint32_t)(rand() % 384);
                q[c][k][i].u = (float)rand() / (float)RAND_MAX;
                q[c][k][i].v = (float)rand() / (float)RAND_MAX;
                q[c][k][i].dudx = q[c][k][i].dvdy = 0.01f;
                memcpy(&sq[i], &q[c][k][i], sizeof sq[i]);
            }
            assert_int_equal(st_sample_batch(s, &so, sq, N, want[c][k], NULL, NULL), 0);
            free(sq);
        }
    stc_conn *conn[C];
    uint32_t ids[C][K];
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 1;
    for (int c = 0; c < C; c++) {
        conn[c] = st_daemon_client(&D1, NULL);
        assert_non_null(conn[c]);
    }
    for (int round = 0; round < 3; round++) {
        for (int c = 0; c < C; c++)
            for (int k = 0; k < K; k++)
                assert_int_equal(stc_append_sample(conn[c], "default", &o, q[c][k], N,
                                                   &ids[c][k]), 0);
        for (int c = 0; c < C; c++)
            assert_int_equal(stc_flush(conn[c]), 0);
        for (int k = 0; k < K; k++)
            for (int c = 0; c < C; c++) {
                stc_reply r;
                assert_int_equal(stc_get_reply(conn[c], 30000, &r), 0);
                assert_int_equal(r.reqid, ids[c][k]);
                assert_int_equal(r.status, 0);
                stc_sample_result res;
                assert_int_equal(stc_reply_sample(conn[c], &r, &res), 0);
                assert_int_equal(res.count, N);
                assert_int_equal(res.nbad, 0);
                assert_memory_equal(res.values, want[c][k], (size_t)N * 4 * sizeof(float));
            }
    }
    const stc_stat *st;
    size_t ns;
    assert_int_equal(stc_stats(conn[0], &st, &ns), 0);
    assert_non_null(stc_stat_find(st, ns, "helpers_yielded"));
    for (int c = 0; c < C; c++) {
        stc_close(conn[c]);
        for (int k = 0; k < K; k++) {
            free(q[c][k]);
            free(want[c][k]);
        }
    }
    st_set_free(s);
}

static void pipelined_requests_come_back_in_order(void **state)
{
    (void)state;
    stc_conn *c = st_daemon_client(&D1, NULL);
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(hello_reports_limits_and_caps),
        cmocka_unit_test(ping_list_info_stats_answer),
        cmocka_unit_test(sample_matches_in_process_sampler),
        cmocka_unit_test(split_batches_match_the_sampler_in_every_form),
        cmocka_unit_test(two_connections_of_split_batches_answer_exactly_in_order),
        cmocka_unit_test(pipelined_requests_come_back_in_order),
    };
    static const char *const args[] = {"--heavy-batch", "2048", NULL};
    st_group_args = args;
    return cmocka_run_group_tests_name("server_sample", tests, st_group_setup,
                                       st_group_teardown);
}
