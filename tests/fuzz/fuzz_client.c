/* tests/fuzz/fuzz_client.c - libFuzzer target for libseamtex facing a hostile server: the
 * input is everything "the server" sends on a connection (then it closes), and the client
 * runs a fixed script of calls against it (pipelined pings, sample, info, list, stats, a
 * job status, a small upload and a fetch into /dev/null-like temp path). Request ids are
 * deterministic (1, 2, ...), so the fuzzer can learn to answer them.
 *
 * Checks without an oracle: no crash, no out-of-bounds access (ASan), no hang (every wait has
 * a deadline and the peer has closed), and the sticky rule: once stc_error() is set, every
 * later call returns exactly that error.
 *
 * The fuzz build links only the store and protocol objects, so the client's sources are
 * compiled into this target directly.
 */
#include "../../client/libconn.c"
#include "../../client/libcalls.c"
#include "../../client/libxfer.c"
#include "../../client/libshm.c"

#define CHECK(c) do { if (!(c)) __builtin_trap(); } while (0)

static stc_conn *conn_on_fd(int fd)
{
    stc_conn *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    c->fd = fd;
    c->next_reqid = 1;
    c->timeout_ms = 200;
    c->max_body = 1u << 20;
    stp_buf_init(&c->out);
    stp_buf_init(&c->in);
    defaults_server(&c->server);
    c->server.max_batch = 4;
    c->server.max_inflight = 4;
    return c;
}

/* After a call: the sticky error, once set, is what every call returns. */
static void sticky_rule(stc_conn *c, int rc)
{
    int s = stc_error(c);
    if (s)
        CHECK(stc_ping(c) == s);
    (void)rc;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    int sv[2];
    if (size > 60000)
        return 0;
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0, sv) != 0)
        return 0;
    size_t off = 0;
    while (off < size) {
        ssize_t w = send(sv[1], data + off, size - off, MSG_NOSIGNAL);
        if (w <= 0)
            break;
        off += (size_t)w;
    }
    shutdown(sv[1], SHUT_WR);
    stc_conn *c = conn_on_fd(sv[0]);
    if (!c) {
        close(sv[0]);
        close(sv[1]);
        return 0;
    }

    uint32_t id;
    stc_reply r;
    int rc;
    for (int i = 0; i < 3; i++)
        stc_append_ping(c, "abc", 3, &id);
    stc_flush(c);
    for (int i = 0; i < 4; i++) {
        rc = stc_get_reply(c, 50, &r);
        if (rc)
            break;
        CHECK(r.errmsg != NULL);
        CHECK(r.body_len == 0 || r.body != NULL);
    }
    sticky_rule(c, 0);

    /* the rest are blocking calls: only valid once nothing pipelined is due */
    while (stc_pending(c) && stc_get_reply(c, 10, &r) == 0)
        ;
    if (stc_pending(c) == 0) {
        stc_query q[6] = { { 0, 0.5f, 0.5f, 0, 0, 0, 0 } };
        stc_sample_opts o;
        stc_sample_result res;
        memset(&o, 0, sizeof o);
        o.want = STC_WANT_COVERAGE | STC_WANT_STATUS;
        rc = stc_sample(c, "tex", &o, q, 6, &res);   /* two parts of max_batch 4 */
        if (rc == 0) {
            CHECK(res.count == 6);
            CHECK(res.nchan >= 1 && res.nchan <= 4);
            volatile uint8_t x = ((const uint8_t *)res.values)[res.count * res.nchan *
                                  stp_outfmt_size(res.outfmt) - 1];
            (void)x;
        }
        sticky_rule(c, rc);
        stc_info inf;
        rc = stc_info_get(c, "tex", 0, 4, &inf);
        if (rc == 0 && inf.nrec)
            CHECK(inf.faces[inf.nrec - 1].nlevels <= 255);
        sticky_rule(c, rc);
        const stc_set_entry *sets;
        size_t n;
        rc = stc_list(c, &sets, &n);
        if (rc == 0 && n)
            CHECK(strlen(sets[n - 1].name) <= STP_MAX_NAME);
        sticky_rule(c, rc);
        const stc_stat *st;
        rc = stc_stats(c, &st, &n);
        if (rc == 0 && n)
            CHECK(st[n - 1].key != NULL);
        sticky_rule(c, rc);
        stc_job job;
        sticky_rule(c, stc_job_status(c, 1, &job));
        stc_upload_opts uo;
        memset(&uo, 0, sizeof uo);
        uo.chunk = 2;
        sticky_rule(c, stc_upload_buffer(c, "hello", 5, "up", &uo, NULL));
        char path[] = "/tmp/fuzz_client_fetch_XXXXXX";
        int fd = mkstemp(path);
        if (fd >= 0) {
            close(fd);
            sticky_rule(c, stc_fetch_file(c, "tex", STC_FETCH_PTX, path, NULL, NULL));
            unlink(path);
        }
    }
    stc_close(c);
    close(sv[1]);
    return 0;
}
