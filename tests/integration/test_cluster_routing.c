/* tests/integration/test_cluster_routing.c - the cluster client's routing rules against a
 * scripted node (docs/cluster.md "Reads and MOVED"), deterministic and without etcd:
 *
 *  - the results of a routed call stay valid until the next call on the handle even when the
 *    call followed a MOVED to a node that the refreshed view no longer lists (the view used to
 *    be refreshed at the end of such a call, which closed the connection the results were in:
 *    the cluster soak read other contents through that);
 *  - NOT_FOUND from the first owner is not final (blocking and pipelined calls): the client
 *    asks the next owner, and answers NOT_FOUND only when every owner says so; when an owner
 *    cannot be reached, it asks the rest of the ranking too.
 *
 *  - the CLI under --cluster follows the same rules (an owner that answers MOVED for a set
 *    another node holds: `seamtex --cluster ... sample` and `info` read it there; they
 *    failed with "MOVED: HOST:PORT" before, the CLI sending every command to the first
 *    reachable owner as it was).
 *
 *  - stc_cluster_open's interrupt hook reaches every node connection, and a call it stops
 *    returns STC_EINTERRUPTED at once, neither failing over nor marking the node down.
 *
 * The scripted node is a thread in this test speaking the wire protocol: HELLO is answered
 * UNKNOWN_OPCODE (version 1 defaults), CLUSTER with the membership the test sets, SAMPLE and
 * INFO with the status and message the test sets. The set itself lives on a real plain
 * seamtexd.
 */
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_fixture.h"
#include "../common/wait.h"
#include "../common/wire.h"
#include "proto.h"
#include "seamtex_cluster.h"
#include "stp_cluster.h"

#define MAXN 4
#define MAXC 8

typedef struct scripted {
    int       lfd, port;
    pthread_t th;
    pthread_mutex_t mu;                 /* guards the script below */
    char      ids[MAXN][16], addrs[MAXN][32];
    size_t    nnodes;
    unsigned  replicas;
    uint16_t  sample_status;
    char      sample_msg[64];
    int       samples, clusters;        /* requests answered */
    int       hang;                     /* 1: SAMPLE / INFO counted, never answered */
    int       stop;                     /* atomic */
} scripted;

static int recv_all(int fd, void *p, size_t n)
{
    size_t got = 0;
    while (got < n) {
        ssize_t k = recv(fd, (char *)p + got, n - got, 0);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return -1;
        got += (size_t)k;
    }
    return 0;
}

/* one request on fd answered; -1 when the peer closed or sent garbage */
static int answer(scripted *s, int fd)
{
    uint8_t head[STP_HEADER_SIZE];
    if (recv_all(fd, head, sizeof head) != 0)
        return -1;
    stp_header h;
    int reason = 0;
    if (stp_parse_header(head, sizeof head, 1u << 20, &h, &reason) != STP_OK)
        return -1;
    uint8_t *body = malloc(h.body_len ? h.body_len : 1);
    if (!body || (h.body_len && recv_all(fd, body, h.body_len) != 0)) {
        free(body);
        return -1;
    }
    free(body);
    stp_buf out;
    stp_buf_init(&out);
    pthread_mutex_lock(&s->mu);
    if (h.opcode == STP_OP_CLUSTER) {
        stp_cluster_node nodes[MAXN];
        for (size_t i = 0; i < s->nnodes; i++) {
            nodes[i].id = s->ids[i];
            nodes[i].id_len = (uint16_t)strlen(s->ids[i]);
            nodes[i].addr = s->addrs[i];
            nodes[i].addr_len = (uint16_t)strlen(s->addrs[i]);
        }
        stp_cluster_reply r;
        memset(&r, 0, sizeof r);
        r.epoch = 1;
        r.replicas = (uint8_t)s->replicas;
        r.write_quorum = (uint8_t)s->replicas;
        r.flags = STP_CLF_ETCD_OK;
        snprintf(r.self_id, sizeof r.self_id, "%s", s->ids[0]);
        r.count = (uint32_t)s->nnodes;
        r.nodes = nodes;
        stp_enc_cluster_reply(&out, h.reqid, &r);
        s->clusters++;
    } else if ((h.opcode == STP_OP_SAMPLE || h.opcode == STP_OP_INFO) && s->hang) {
        s->samples++;                   /* a hung node: the request is read, no reply */
    } else if (h.opcode == STP_OP_SAMPLE || h.opcode == STP_OP_INFO) {
        stp_enc_error(&out, h.opcode, h.reqid, s->sample_status, s->sample_msg);
        s->samples++;
    } else {
        stp_enc_error(&out, h.opcode, h.reqid, STP_S_UNKNOWN_OPCODE, "scripted node");
    }
    pthread_mutex_unlock(&s->mu);
    if (out.len == out.start && !out.err) {
        stp_buf_free(&out);
        return 0;
    }
    ssize_t w = out.err ? -1 : send(fd, out.data + out.start, out.len - out.start, MSG_NOSIGNAL);
    int rc = w == (ssize_t)(out.len - out.start) ? 0 : -1;
    stp_buf_free(&out);
    return rc;
}

static void *scripted_main(void *arg)
{
    scripted *s = arg;
    struct pollfd p[1 + MAXC];
    size_t n = 1;
    p[0].fd = s->lfd;
    p[0].events = POLLIN;
    while (!__atomic_load_n(&s->stop, __ATOMIC_RELAXED)) {
        if (poll(p, n, 50) <= 0)
            continue;
        for (size_t i = n; i-- > 1;)
            if (p[i].revents && answer(s, p[i].fd) != 0) {
                close(p[i].fd);
                p[i] = p[--n];
            }
        if (p[0].revents & POLLIN) {
            int fd = accept(s->lfd, NULL, NULL);
            if (fd >= 0 && n < 1 + MAXC) {
                p[n].fd = fd;
                p[n].events = POLLIN;
                p[n++].revents = 0;
            } else if (fd >= 0) {
                close(fd);
            }
        }
    }
    for (size_t i = 1; i < n; i++)
        close(p[i].fd);
    return NULL;
}

static int scripted_start(scripted *s)
{
    memset(s, 0, sizeof *s);
    pthread_mutex_init(&s->mu, NULL);
    s->lfd = st_wire_listen(8, &s->port);
    if (s->lfd < 0)
        return -1;
    return pthread_create(&s->th, NULL, scripted_main, s) == 0 ? 0 : -1;
}

static void scripted_stop(scripted *s)
{
    __atomic_store_n(&s->stop, 1, __ATOMIC_RELAXED);
    pthread_join(s->th, NULL);
    close(s->lfd);
    pthread_mutex_destroy(&s->mu);
}

/* the membership the scripted node reports: "a" (itself), then "d" at d_addr and "b" at
 * b_addr for those that are not NULL */
static void script_members(scripted *s, unsigned replicas, const char *d_addr,
                           const char *b_addr)
{
    pthread_mutex_lock(&s->mu);
    snprintf(s->ids[0], sizeof s->ids[0], "a");
    snprintf(s->addrs[0], sizeof s->addrs[0], "127.0.0.1:%d", s->port);
    s->nnodes = 1;
    const char *ids[2] = {"d", "b"}, *addrs[2] = {d_addr, b_addr};
    for (int i = 0; i < 2; i++)
        if (addrs[i]) {
            snprintf(s->ids[s->nnodes], sizeof s->ids[0], "%s", ids[i]);
            snprintf(s->addrs[s->nnodes], sizeof s->addrs[0], "%s", addrs[i]);
            s->nnodes++;
        }
    s->replicas = replicas;
    pthread_mutex_unlock(&s->mu);
}

static void script_sample(scripted *s, uint16_t status, const char *msg)
{
    pthread_mutex_lock(&s->mu);
    s->sample_status = status;
    snprintf(s->sample_msg, sizeof s->sample_msg, "%s", msg);
    pthread_mutex_unlock(&s->mu);
}

/* ---- fixtures: one plain daemon holding "tint" ------------------------------------------- */

static st_daemon D;
static char daddr[32];
static float tint_red;

static int group_setup(void **state)
{
    (void)state;
    if (st_daemon_up(&D, NULL) != 0)
        return -1;
    snprintf(daddr, sizeof daddr, "127.0.0.1:%d", D.port);
    char files[1][300];
    if (st_cluster_tint_files(D.dir, 1, 40, files) != 0)
        return -1;
    int err = 0;
    char msg[256];
    stc_conn *c = stc_connect_opts("127.0.0.1", (unsigned)D.port, NULL, &err, msg, sizeof msg);
    int rc = c ? stc_upload_file(c, files[0], "tint", NULL, NULL) : -1;
    if (rc == 0)
        rc = st_red_at(c, "tint", &tint_red);
    stc_close(c);
    return rc;
}

static int group_teardown(void **state)
{
    (void)state;
    return st_daemon_down(&D, 10000) == 0 ? 0 : -1;
}

static stc_cluster *open_at(const scripted *s)
{
    char seed[32], msg[256];
    snprintf(seed, sizeof seed, "127.0.0.1:%d", s->port);
    int err = 0;
    stc_cluster *cl = stc_cluster_open(seed, NULL, &err, msg, sizeof msg);
    if (!cl)
        fail_msg("stc_cluster_open: %s", msg);
    return cl;
}

/* a routed read of name gives the tint */
static void assert_red(stc_cluster *cl, const char *name)
{
    float red = -1;
    assert_int_equal(st_cluster_red_at(cl, name, &red), 0);
    assert_true(red == tint_red);
}

/* ---- the tests ------------------------------------------------------------------------------ */

static void results_survive_the_refresh_after_a_moved(void **state)
{
    (void)state;
    scripted s;
    assert_int_equal(scripted_start(&s), 0);
    script_members(&s, 1, NULL, NULL);      /* the view never lists the daemon */
    script_sample(&s, STP_S_MOVED, daddr);  /* ... but "a" sends every SAMPLE to it */
    stc_cluster *cl = open_at(&s);
    /* the client refreshes its view at most every 500 ms: past that, the call below asks for
     * a refresh (it followed a MOVED), and the refresh drops the daemon from the view */
    st_sleep_ms(600);
    float got = -1;   /* read from the call's results after it returned */
    assert_int_equal(st_cluster_red_at(cl, "tint", &got), 0);
    assert_true(got == tint_red);
    stc_cluster_counters n;
    stc_cluster_get_counters(cl, &n);
    assert_int_equal(n.moved, 1);
    /* the next call runs the refresh: the view is the scripted one again */
    got = -1;
    assert_int_equal(st_cluster_red_at(cl, "tint", &got), 0);
    assert_true(got == tint_red);
    stc_cluster_get_counters(cl, &n);
    assert_true(n.refreshes >= 2);
    stc_cluster_close(cl);
    scripted_stop(&s);
}

/* the daemon holds the tint under name too */
static void upload_to_daemon(const char *name)
{
    char files[1][300];
    assert_int_equal(st_cluster_tint_files(D.dir, 1, 40, files), 0);
    int err = 0;
    char msg[256];
    stc_conn *c = stc_connect_opts("127.0.0.1", (unsigned)D.port, NULL, &err, msg, sizeof msg);
    assert_non_null(c);
    assert_int_equal(stc_upload_file(c, files[0], name, NULL, NULL), 0);
    stc_close(c);
}

/* a set name whose first owner among {"a", "d"} is "a" */
static void name_owned_first_by_a(char *out, size_t cap)
{
    const char *ids[2] = {"a", "d"};
    for (int k = 0;; k++) {
        snprintf(out, cap, "set%d", k);
        size_t order[2];
        stp_hrw_rank(ids, 2, out, order, 2);
        if (order[0] == 0)
            return;
    }
}

/* the same read pipelined (stc_cluster_append_sample / get_reply): its status, and the red
 * value when OK */
static int pipelined_red(stc_cluster *cl, const char *name, float *red)
{
    stc_sample_opts o;
    stc_query q;
    st_red_query(&o, &q);
    uint32_t id = 0;
    assert_int_equal(stc_cluster_append_sample(cl, name, &o, &q, 1, &id), 0);
    stc_cluster_reply r;
    assert_int_equal(stc_cluster_get_reply(cl, -1, &r), 0);
    assert_int_equal(r.reqid, id);
    stc_sample_result res;
    int rc = stc_cluster_reply_sample(&r, &res);
    if (rc == 0)
        *red = ((const float *)res.values)[0];
    return rc;
}

/* a node's refusal (not NOT_FOUND, not a lost connection) is the call's answer, and
 * stc_cluster_errmsg gives its message (it was empty: a cluster upload refused with FORMAT
 * printed "upload s00: "); a later success leaves no message behind */
static void a_refusal_s_message_is_the_call_s_message(void **state)
{
    (void)state;
    scripted s;
    assert_int_equal(scripted_start(&s), 0);
    script_members(&s, 1, NULL, NULL);
    script_sample(&s, STP_S_BAD_REQUEST, "query 3: face 99 out of range");
    stc_cluster *cl = open_at(&s);
    float red = -1;
    assert_int_equal(st_cluster_red_at(cl, "anything", &red), STC_EBADREQUEST);
    const char *m = stc_cluster_errmsg(cl);
    if (!strstr(m, "query 3: face 99 out of range") || !strstr(m, "node a"))
        fail_msg("stc_cluster_errmsg: \"%s\"", m);

    /* "a" now says NOT_FOUND and the daemon ("d") holds "tint": the call succeeds (on "d",
     * after "a" when "a" ranks first) and leaves no message */
    script_members(&s, 2, daddr, NULL);
    script_sample(&s, STP_S_NOT_FOUND, "no such set here yet");
    assert_int_equal(stc_cluster_refresh(cl), 0);
    assert_red(cl, "tint");
    assert_string_equal(stc_cluster_errmsg(cl), "");
    stc_cluster_close(cl);
    scripted_stop(&s);
}

static void not_found_from_one_owner_asks_the_next(void **state)
{
    (void)state;
    scripted s;
    assert_int_equal(scripted_start(&s), 0);
    script_members(&s, 2, daddr, NULL);     /* owners "a" (scripted) and "d" (the daemon) */
    script_sample(&s, STP_S_NOT_FOUND, "no such set here yet");
    char name[32];
    name_owned_first_by_a(name, sizeof name);
    /* the daemon holds it under that name too */
    upload_to_daemon(name);

    stc_cluster *cl = open_at(&s);
    assert_red(cl, name);
    pthread_mutex_lock(&s.mu);
    int asked = s.samples;
    pthread_mutex_unlock(&s.mu);
    assert_int_equal(asked, 1);             /* "a" was asked first and said NOT_FOUND */

    /* a set no owner holds: NOT_FOUND once both owners said so */
    char other[32];
    for (int k = 0;; k++) {
        snprintf(other, sizeof other, "none%d", k);
        const char *ids[2] = {"a", "d"};
        size_t order[2];
        stp_hrw_rank(ids, 2, other, order, 2);
        if (order[0] == 0)
            break;
    }
    float red = -1;
    assert_int_equal(st_cluster_red_at(cl, other, &red), STC_ENOTFOUND);
    pthread_mutex_lock(&s.mu);
    asked = s.samples;
    pthread_mutex_unlock(&s.mu);
    assert_int_equal(asked, 2);

    /* the pipelined calls follow the same rule: a's NOT_FOUND sends the request on to d */
    red = -1;
    assert_int_equal(pipelined_red(cl, name, &red), 0);
    assert_true(red == tint_red);
    assert_int_equal(pipelined_red(cl, other, &red), STC_ENOTFOUND);
    pthread_mutex_lock(&s.mu);
    asked = s.samples;
    pthread_mutex_unlock(&s.mu);
    assert_int_equal(asked, 4);             /* "a" was asked first both times */
    stc_cluster_close(cl);
    scripted_stop(&s);
}

/* "a" (NOT_FOUND) and "b" (unreachable) own the set, "d" (not an owner) holds it: as after a
 * membership change whose new owners have not received their copies yet */
static void not_found_with_an_owner_unreachable_asks_the_rest(void **state)
{
    (void)state;
    scripted s;
    assert_int_equal(scripted_start(&s), 0);
    /* an address nothing listens on: a port bound and closed again */
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t al = sizeof a;
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(getsockname(fd, (struct sockaddr *)&a, &al), 0);
    close(fd);
    char baddr[32];
    snprintf(baddr, sizeof baddr, "127.0.0.1:%d", ntohs(a.sin_port));
    script_members(&s, 2, daddr, baddr);
    script_sample(&s, STP_S_NOT_FOUND, "no such set here yet");
    char name[32];
    const char *ids[3] = {"a", "d", "b"};
    for (int k = 0;; k++) {
        snprintf(name, sizeof name, "moved%d", k);
        size_t order[3];
        stp_hrw_rank(ids, 3, name, order, 3);
        if (order[0] == 0 && order[1] == 2)
            break;                          /* owners a then b; d last */
    }
    upload_to_daemon(name);
    stc_cluster *cl = open_at(&s);
    assert_red(cl, name);
    /* at once again: "b" failed a moment ago, so it is tried last (a, d, b); after a's
     * NOT_FOUND the client must still come back to d once b fails */
    assert_red(cl, name);
    stc_cluster_close(cl);
    scripted_stop(&s);
}

/* the interrupt hook of the test below: stops a wait once armed for 200 ms */
typedef struct stopper {
    int     armed, calls;
    int64_t t0;
} stopper;

static int stop_after_200ms(void *user)
{
    stopper *st = user;
    if (!st->armed)
        return 0;
    st->calls++;
    return st_now_ms() - st->t0 >= 200;
}

/* a set name whose first owner among ids[0..n) is ids[first] and second ids[second] */
static void name_ranked(const char *const *ids, size_t n, size_t first, size_t second,
                        char *out, size_t cap)
{
    for (int k = 0;; k++) {
        snprintf(out, cap, "intr%d", k);
        size_t order[3];
        stp_hrw_rank(ids, n, out, order, n);
        if (order[0] == first && order[1] == second)
            return;
    }
}

/* stc_opts.interrupt of stc_cluster_open is every node connection's hook, and an interrupted
 * routed call returns STC_EINTERRUPTED at once: no failover to the next node (left36). First
 * the set's first owner "b" is a socket that accepts and never answers (its HELLO waits: the
 * interrupted connect failed over to "d", which holds the set, and the call succeeded), then
 * its first owner "a" (the scripted node) reads the SAMPLE and never answers (the reply's
 * wait). Both: STC_EINTERRUPTED after ~200 ms, failovers +0, the hook asked; the handle then
 * reads the set (a's NOT_FOUND, then d). A pipelined append to b likewise returns
 * STC_EINTERRUPTED (it was sent to d). */
static void an_interrupted_call_does_not_fail_over(void **state)
{
    (void)state;
    scripted s;
    assert_int_equal(scripted_start(&s), 0);
    int hport = 0;
    int hfd = st_wire_listen(8, &hport);     /* listens, never accepts: connects, no HELLO */
    assert_true(hfd >= 0);
    char haddr[32];
    snprintf(haddr, sizeof haddr, "127.0.0.1:%d", hport);
    script_members(&s, 2, daddr, haddr);     /* a, d, b (= the hung socket) */
    script_sample(&s, STP_S_NOT_FOUND, "no such set here");
    const char *ids[3] = {"a", "d", "b"};
    char hung_connect[32], hung_reply[32];
    name_ranked(ids, 3, 2, 1, hung_connect, sizeof hung_connect);   /* b, then d */
    name_ranked(ids, 3, 0, 1, hung_reply, sizeof hung_reply);       /* a, then d */
    upload_to_daemon(hung_connect);
    upload_to_daemon(hung_reply);

    stopper st = {0, 0, 0};
    stc_opts o = {.interrupt = stop_after_200ms, .interrupt_user = &st,
                  .interrupt_every_ms = 50};
    char seed[32], msg[256];
    snprintf(seed, sizeof seed, "127.0.0.1:%d", s.port);
    int err = 0;
    stc_cluster *cl = stc_cluster_open(seed, &o, &err, msg, sizeof msg);
    if (!cl)
        fail_msg("stc_cluster_open: %s", msg);
    const char *names[2] = {hung_connect, hung_reply};
    for (int k = 0; k < 2; k++) {
        pthread_mutex_lock(&s.mu);
        s.hang = k == 1;
        int samples0 = s.samples;
        pthread_mutex_unlock(&s.mu);
        stc_cluster_counters c0, c1;
        stc_cluster_get_counters(cl, &c0);
        st.calls = 0;
        st.t0 = st_now_ms();
        st.armed = 1;
        float red = -1;
        int rc = st_cluster_red_at(cl, names[k], &red);
        int64_t took = st_now_ms() - st.t0;
        st.armed = 0;
        stc_cluster_get_counters(cl, &c1);
        pthread_mutex_lock(&s.mu);
        int asked = s.samples - samples0;
        pthread_mutex_unlock(&s.mu);
        printf("# %s: %s after %lld ms, %d hook call(s), failovers +%llu, \"%s\"\n",
               k ? "a reply never sent" : "a HELLO never answered", stc_strerror(rc),
               (long long)took, st.calls, (unsigned long long)(c1.failovers - c0.failovers),
               stc_cluster_errmsg(cl));
        assert_int_equal(rc, STC_EINTERRUPTED);
        assert_true(st.calls >= 1);
        assert_int_equal(c1.failovers - c0.failovers, 0);
        assert_int_equal(asked, k == 1 ? 1 : 0);   /* a was asked only when it was first */
        assert_true(took < 4000);                    /* the hook, not a timeout, ended it */
        if (k == 0) {
            /* pipelined: the append's connect to b, stopped, is the append's answer (it was
             * sent to d instead) */
            stc_sample_opts so;
            stc_query q;
            st_red_query(&so, &q);
            uint32_t id = 0;
            st.t0 = st_now_ms();
            st.armed = 1;
            rc = stc_cluster_append_sample(cl, names[k], &so, &q, 1, &id);
            st.armed = 0;
            stc_cluster_get_counters(cl, &c1);
            printf("# pipelined, a HELLO never answered: %s, failovers +%llu\n",
                   stc_strerror(rc), (unsigned long long)(c1.failovers - c0.failovers));
            assert_int_equal(rc, STC_EINTERRUPTED);
            assert_int_equal(c1.failovers - c0.failovers, 0);
        }
    }
    /* the handle is usable: a answers (NOT_FOUND) and d gives the set */
    pthread_mutex_lock(&s.mu);
    s.hang = 0;
    pthread_mutex_unlock(&s.mu);
    assert_red(cl, hung_reply);
    stc_cluster_close(cl);
    close(hfd);
    scripted_stop(&s);
}

/* the CLI: "a" owns the set first and answers MOVED to "d", which holds it */
static void the_cli_follows_moved_to_the_node_that_holds_the_set(void **state)
{
    (void)state;
    scripted s;
    assert_int_equal(scripted_start(&s), 0);
    script_members(&s, 2, daddr, NULL);
    script_sample(&s, STP_S_MOVED, daddr);
    char name[32], seeds[40], out[4096];
    const char *ids[2] = {"a", "d"};
    for (int k = 0;; k++) {   /* a name of its own (the daemon keeps the other cases' sets) */
        snprintf(name, sizeof name, "cli%d", k);
        size_t order[2];
        stp_hrw_rank(ids, 2, name, order, 2);
        if (order[0] == 0)
            break;
    }
    upload_to_daemon(name);
    snprintf(seeds, sizeof seeds, "127.0.0.1:%d", s.port);
    const char *sample[] = {"sample", name, "0", "0.5", "0.5", NULL};
    int st = st_cluster_cli(D.dir, seeds, sample, out, sizeof out);
    if (st != 0 || !strstr(out, "OK"))
        fail_msg("seamtex --cluster %s sample %s: exit %d: %s", seeds, name, st, out);
    const char *info[] = {"info", name, NULL};
    st = st_cluster_cli(D.dir, seeds, info, out, sizeof out);
    if (st != 0 || !strstr(out, name))
        fail_msg("seamtex --cluster %s info %s: exit %d: %s", seeds, name, st, out);
    scripted_stop(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(the_cli_follows_moved_to_the_node_that_holds_the_set),
        cmocka_unit_test(not_found_with_an_owner_unreachable_asks_the_rest),
        cmocka_unit_test(results_survive_the_refresh_after_a_moved),
        cmocka_unit_test(not_found_from_one_owner_asks_the_next),
        cmocka_unit_test(a_refusal_s_message_is_the_call_s_message),
        cmocka_unit_test(an_interrupted_call_does_not_fail_over),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
