/* tests/integration/test_cluster_soak.c - the cluster soak (docs/cluster.md, Tests): a real
 * etcd on loopback and 3 seamtexd nodes with R=2, W=2 and 2 s leases; an uploader thread
 * uploads distinct small sets through the cluster client and records the acknowledged ones, a
 * reader thread samples acknowledged sets through the cluster client; each round the test
 * kills one random node with SIGKILL at a random moment, waits a random short time and
 * restarts it with the same data dir and node id (at most one node is down at a time: R=2),
 * then waits until every node sees every node again. At the end, after a bounded wait for
 * convergence: zero acknowledged uploads lost (each one reads back with its own contents
 * through the cluster client and through each of its owners directly) and zero sets with
 * fewer than R copies among the acknowledged ones (counted from every node's LIST); every copy
 * on any node has the contents uploaded under its name (also the leftover of a refused upload)
 * and no node holds a set nobody uploaded; no read during the rounds gave other contents.
 *
 * Also asserted: zero failed reads during the rounds (a node that has just restarted and does
 * not hold a set yet answers MOVED or NOT_FOUND, and the cluster client then asks the next
 * owner), and no refused upload left on fewer than R nodes after 20 s more of repair (the
 * claim of an origin killed before its W acks is abandoned once the origin is gone or has
 * restarted, and its copy dropped). The reader takes each red value both inside the routed
 * call and after it returned, so that a reply the client clobbered after the call (which the
 * soak once found: test_cluster_routing) is told apart from other contents served by a node.
 *
 * Rounds: SEAMTEX_SOAK_ROUNDS when set, else 20 under make soak (SEAMTEX_SOAK_SECONDS is set
 * there), else 3 (make test's bounded slice, and a run by hand). SEAMTEX_SOAK_SEED
 * replays a run (the seed is printed). The sleeps are the random kill moments and down times
 * under test; every other wait is a deadline against a hang, never a speed check.
 */
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "../common/cluster_fixture.h"
#include "../common/daemon_client.h"
#include "../common/etcd_fixture.h"
#include "../common/wait.h"
#include "seamtex_cluster.h"

#define NNODES 3
#define R 2
#define NTINT 8            /* distinct contents, cycled through the uploads */
#define MAXSETS 4000       /* the uploader stops at this many names */
#define CONVERGE_MS 180000
#define SETTLE_MS 60000
#define LEFTOVER_MS 20000

typedef struct soak {
    st_etcd  etcd;
    st_daemon node[NNODES];
    char     files[NTINT][300];
    float    red[NTINT];            /* the red value of each tint */
    pthread_mutex_t mu;             /* guards seeds */
    char     seeds[256];            /* every node's current address */
    int      stop;                  /* atomic: the threads end */
    int      named;                 /* atomic: names u00000.. handed to the uploader */
    signed char acked[MAXSETS];     /* atomic per entry: 1 when the upload was acknowledged */
    /* counters (each written by one thread, read after the join) */
    uint64_t uploads, upload_failures, reads, read_failures, wrong_reads;
    char     first_read_failure[512], first_upload_failure[512], first_wrong_read[128];
} soak;

static soak S;

static void setname(char *out, int k) { snprintf(out, 16, "u%05d", k); }

static void update_seeds(soak *s)
{
    char buf[256];
    size_t off = 0;
    for (int i = 0; i < NNODES; i++)
        off += (size_t)snprintf(buf + off, sizeof buf - off, "%s127.0.0.1:%d", i ? "," : "",
                                s->node[i].port);
    pthread_mutex_lock(&s->mu);
    snprintf(s->seeds, sizeof s->seeds, "%s", buf);
    pthread_mutex_unlock(&s->mu);
}

/* a cluster handle from the current addresses (ports change on a restart); NULL while no
 * seed answers */
static stc_cluster *open_cluster(soak *s)
{
    char seeds[256], msg[256];
    pthread_mutex_lock(&s->mu);
    snprintf(seeds, sizeof seeds, "%s", s->seeds);
    pthread_mutex_unlock(&s->mu);
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 3000;
    int err = 0;
    return stc_cluster_open(seeds, &o, &err, msg, sizeof msg);
}

static int is_conn_error(int rc)
{
    return rc == STC_ECONNECT || rc == STC_EIO || rc == STC_ECLOSED || rc == STC_ETIMEDOUT;
}

static int stopping(soak *s) { return __atomic_load_n(&s->stop, __ATOMIC_RELAXED); }

/* ---- the uploader and the reader ------------------------------------------------------------ */

static void *uploader_main(void *arg)
{
    soak *s = arg;
    stc_cluster *cl = NULL;
    while (!stopping(s)) {
        int k = __atomic_load_n(&s->named, __ATOMIC_RELAXED);
        if (k >= MAXSETS)
            break;
        if (!cl && !(cl = open_cluster(s))) {
            st_sleep_ms(100);   /* no seed answered: a node is restarting */
            continue;
        }
        char name[16];
        setname(name, k);
        __atomic_store_n(&s->named, k + 1, __ATOMIC_RELEASE);
        int rc = stc_cluster_upload_file(cl, s->files[k % NTINT], name, NULL, NULL);
        s->uploads++;
        if (rc == 0) {
            __atomic_store_n(&s->acked[k], 1, __ATOMIC_RELEASE);
        } else {
            if (!s->upload_failures)
                snprintf(s->first_upload_failure, sizeof s->first_upload_failure, "%s: %s (%s)",
                         name, stc_strerror(rc), stc_cluster_errmsg(cl));
            s->upload_failures++;
            if (is_conn_error(rc) || rc == STC_EUNAVAILABLE) {
                stc_cluster_close(cl);
                cl = NULL;
            }
        }
        st_sleep_ms(20);   /* a steady load, not a flood, on a shared machine */
    }
    stc_cluster_close(cl);
    return NULL;
}

/* the reader's routed SAMPLE: the red value is taken both inside the call (from the reply the
 * answering node gave) and after it returned (what a caller of stc_cluster_sample sees) */
typedef struct red_arg {
    const char *set;
    float inside;
    stc_sample_result res;
} red_arg;

static int do_red(stc_conn *c, void *p)
{
    red_arg *a = p;
    stc_sample_opts o;
    stc_query q;
    st_red_query(&o, &q);
    int rc = stc_sample(c, a->set, &o, &q, 1, &a->res);
    if (rc == 0)
        a->inside = ((const float *)a->res.values)[0];
    return rc;
}

static void *reader_main(void *arg)
{
    soak *s = arg;
    unsigned seed = 12345;
    stc_cluster *cl = NULL;
    while (!stopping(s)) {
        int n = __atomic_load_n(&s->named, __ATOMIC_ACQUIRE);
        int k = n ? (int)(rand_r(&seed) % (unsigned)n) : 0;
        if (!n || !__atomic_load_n(&s->acked[k], __ATOMIC_ACQUIRE)) {
            st_sleep_ms(1);
            continue;
        }
        if (!cl && !(cl = open_cluster(s))) {
            st_sleep_ms(100);
            continue;
        }
        char name[16];
        setname(name, k);
        float red = -1;
        red_arg ra = {name, -1, {0}};
        int rc = stc_cluster_call(cl, name, do_red, &ra, NULL);
        if (rc == 0)
            red = ((const float *)ra.res.values)[0];
        s->reads++;
        if (rc != 0 || red != S.red[k % NTINT]) {
            if (rc && !s->read_failures)
                snprintf(s->first_read_failure, sizeof s->first_read_failure, "%s: %s (%s)",
                         name, stc_strerror(rc), stc_cluster_errmsg(cl));
            if (!rc && !s->wrong_reads)
                snprintf(s->first_wrong_read, sizeof s->first_wrong_read,
                         "%s: red %g (inside the call %g), uploaded %g", name, (double)red,
                         (double)ra.inside, (double)S.red[k % NTINT]);
            if (rc)
                s->read_failures++;
            else
                s->wrong_reads++;
            if (is_conn_error(rc)) {
                stc_cluster_close(cl);
                cl = NULL;
            }
        }
    }
    stc_cluster_close(cl);
    return NULL;
}

/* ---- convergence ----------------------------------------------------------------------------- */

/* every node sees every node through a working etcd */
static int members_settled(void *arg)
{
    soak *s = arg;
    for (int i = 0; i < NNODES; i++)
        if (st_daemon_stat(&s->node[i], "cluster_members") != NNODES ||
            st_daemon_stat(&s->node[i], "cluster_etcd_ok") != 1)
            return 0;
    return 1;
}

typedef struct verdict {
    int  copies[MAXSETS];
    int  short_sets, lost, wrong, strangers, owner_misses;
    int  unreadable;            /* listed, then gone (repair dropped an extra copy) */
    int  leftovers;             /* refused uploads left on fewer than R nodes */
    char leftover_names[96];
    char first[256];
} verdict;

static void note(verdict *v, const char *fmt, const char *name)
{
    if (!v->first[0])
        snprintf(v->first, sizeof v->first, fmt, name);
}

/* counts copies on every node (LIST, each copy's contents checked), then reads each
 * acknowledged set through the cluster client and its owners; fills v; 1 when all is well */
static int check_all(soak *s, verdict *v)
{
    memset(v, 0, sizeof *v);
    int n = __atomic_load_n(&s->named, __ATOMIC_ACQUIRE);
    for (int i = 0; i < NNODES; i++) {
        stc_conn *c = st_daemon_client(&s->node[i], NULL);
        const stc_set_entry *sets;
        size_t ns;
        if (!c || stc_list(c, &sets, &ns) != 0) {
            stc_close(c);
            note(v, "a node did not answer LIST%s", "");
            return 0;
        }
        char (*names)[16] = malloc(ns * sizeof *names + 1);
        for (size_t j = 0; j < ns; j++)
            snprintf(names[j], 16, "%s", sets[j].name);
        for (size_t j = 0; j < ns; j++) {
            int k = names[j][0] == 'u' ? atoi(names[j] + 1) : -1;
            if (k < 0 || k >= n) {
                v->strangers++;
                note(v, "a set nobody uploaded: %s", names[j]);
                continue;
            }
            float red = -1;
            if (st_red_at(c, names[j], &red) != 0) {
                v->unreadable++;   /* dropped by repair between LIST and SAMPLE: not a copy */
                continue;
            }
            if (red != s->red[k % NTINT]) {
                v->wrong++;
                note(v, "%s: other contents on a node", names[j]);
                continue;
            }
            v->copies[k]++;
        }
        free(names);
        stc_close(c);
    }
    for (int k = 0; k < n; k++) {
        char name[16];
        setname(name, k);
        if (s->acked[k] && !v->copies[k]) {
            v->lost++;
            note(v, "%s: acknowledged, on no node", name);
        } else if (s->acked[k] && v->copies[k] < R) {
            v->short_sets++;
            note(v, "%s: acknowledged, fewer than R copies", name);
        } else if (!s->acked[k] && v->copies[k] && v->copies[k] < R) {
            v->leftovers++;   /* given LEFTOVER_MS more, then a failure */
            size_t l = strlen(v->leftover_names);
            if (l < sizeof v->leftover_names - 8)
                snprintf(v->leftover_names + l, sizeof v->leftover_names - l, " %s", name);
        }
    }
    stc_cluster *cl = open_cluster(s);
    if (!cl) {
        note(v, "no node answered CLUSTER%s", "");
        return 0;
    }
    for (int k = 0; k < n; k++) {
        if (!s->acked[k])
            continue;
        char name[16];
        setname(name, k);
        float red = -1;
        if (st_cluster_red_at(cl, name, &red) != 0 || red != s->red[k % NTINT]) {
            v->lost++;
            note(v, "%s: not read back through the cluster client", name);
        }
        size_t idx[R];
        size_t no = stc_cluster_rank(cl, name, idx, R);
        for (size_t j = 0; j < no; j++) {
            int err = 0;
            stc_conn *c = stc_cluster_conn(cl, idx[j], &err);
            red = -1;
            if (!c || st_red_at(c, name, &red) != 0 || red != s->red[k % NTINT]) {
                v->owner_misses++;
                note(v, "%s: an owner does not serve it", name);
            }
        }
        if (no != R) {
            v->owner_misses++;
            note(v, "%s: fewer than R owners in the view", name);
        }
    }
    stc_cluster_close(cl);
    return !v->short_sets && !v->lost && !v->wrong && !v->strangers && !v->owner_misses;
}

static int converged(void *arg)
{
    static verdict v;
    return check_all(arg, &v);
}

/* converged, and no refused upload left on fewer than R nodes (repair drops such leftovers) */
static int no_leftovers(void *arg)
{
    static verdict v;
    return check_all(arg, &v) && !v.leftovers;
}

static long env_long(const char *name, long dflt)
{
    const char *e = getenv(name);
    return e && *e ? strtol(e, NULL, 10) : dflt;
}

/* ---- the test ---------------------------------------------------------------------------------- */

static void cluster_soak_kills_and_restarts(void **state)
{
    (void)state;
    soak *s = &S;
    long rounds = env_long("SEAMTEX_SOAK_ROUNDS", getenv("SEAMTEX_SOAK_SECONDS") ? 20 : 3);
    unsigned seed = (unsigned)env_long("SEAMTEX_SOAK_SEED", (long)time(NULL));
    print_message("cluster soak: %ld rounds, seed %u (SEAMTEX_SOAK_SEED replays)\n", rounds,
                  seed);
    int64_t t0 = st_now_ms();
    pthread_mutex_init(&s->mu, NULL);
    assert_int_equal(st_etcd_start(&s->etcd, "/soak"), 0);
    for (int i = 0; i < NNODES; i++)
        assert_int_equal(st_daemon_init(&s->node[i]), 0);
    assert_int_equal(st_cluster_tint_files(s->node[0].dir, NTINT, 30, s->files), 0);
    for (int i = 0; i < NNODES; i++)
        assert_int_equal(st_cluster_node_start(&s->node[i], s->etcd.url, i, R, R), 0);
    update_seeds(s);
    if (st_wait_until(members_settled, s, SETTLE_MS) != 0)
        fail_msg("the nodes never saw each other");
    stc_cluster *cl = open_cluster(s);
    assert_non_null(cl);
    if (st_cluster_tint_reds(cl, NTINT, s->files, s->red) != 0)
        fail_msg("probe uploads: %s", stc_cluster_errmsg(cl));
    stc_cluster_close(cl);
    for (int a = 0; a < NTINT; a++)
        for (int b = a + 1; b < NTINT; b++)
            assert_true(s->red[a] != s->red[b]);

    pthread_t up, rd;
    assert_int_equal(pthread_create(&up, NULL, uploader_main, s), 0);
    assert_int_equal(pthread_create(&rd, NULL, reader_main, s), 0);
    for (long r = 0; r < rounds; r++) {
        int victim = (int)(rand_r(&seed) % NNODES);
        st_sleep_ms(300 + (int)(rand_r(&seed) % 1200));   /* a random moment under load */
        st_daemon_kill(&s->node[victim]);
        int down_ms = 200 + (int)(rand_r(&seed) % 3000);  /* sometimes past the 2 s lease */
        st_sleep_ms(down_ms);
        if (st_cluster_node_start(&s->node[victim], s->etcd.url, victim, R, R) != 0)
            fail_msg("round %ld: n%d did not restart", r + 1, victim);
        update_seeds(s);
        if (st_wait_until(members_settled, s, SETTLE_MS) != 0) {
            for (int i = 0; i < NNODES; i++)
                st_daemon_dump_log(&s->node[i], 20);
            fail_msg("round %ld: the nodes did not see each other again", r + 1);
        }
        print_message("round %ld: n%d killed, down %d ms; %d names, %llu upload failures\n",
                      r + 1, victim, down_ms, __atomic_load_n(&s->named, __ATOMIC_RELAXED),
                      (unsigned long long)s->upload_failures);
    }
    __atomic_store_n(&s->stop, 1, __ATOMIC_RELAXED);
    pthread_join(up, NULL);
    pthread_join(rd, NULL);

    int n = s->named;
    uint64_t acked = 0;
    for (int k = 0; k < n; k++)
        acked += (uint64_t)s->acked[k];
    int64_t t_conv = st_now_ms();
    int ok = st_wait_until(converged, s, CONVERGE_MS) == 0;
    /* leftovers get a few repair passes and the 2 TTLs after which a claim is abandoned */
    if (ok)
        st_wait_until(no_leftovers, s, LEFTOVER_MS);
    static verdict v;
    check_all(s, &v);
    char load[64] = "?";
    FILE *lf = fopen("/proc/loadavg", "r");
    if (lf && fgets(load, sizeof load, lf))
        load[strcspn(load, "\n")] = 0;
    if (lf)
        fclose(lf);
    print_message("cluster soak (load average %s): %ld rounds in %.1f s (convergence %.1f s): %llu uploads tried, "
                  "%llu acknowledged, %llu failed (first: %s); %llu reads, %llu failed (first: %s), "
                  "%llu other contents (first: %s); at the end: %d lost, %d under R copies, %d copies "
                  "of other contents, %d listed then gone, %d unknown sets, %d owner misses; refused uploads left on fewer than "
                  "R nodes: %d%s\n",
                  load, rounds, (double)(st_now_ms() - t0) / 1000, (double)(st_now_ms() - t_conv) / 1000,
                  (unsigned long long)s->uploads, (unsigned long long)acked,
                  (unsigned long long)s->upload_failures, s->first_upload_failure,
                  (unsigned long long)s->reads, (unsigned long long)s->read_failures,
                  s->first_read_failure, (unsigned long long)s->wrong_reads, s->first_wrong_read,
                  v.lost, v.short_sets, v.wrong, v.unreadable, v.strangers, v.owner_misses, v.leftovers, v.leftover_names);
    if (!ok) {
        for (int i = 0; i < NNODES; i++)
            st_daemon_dump_log(&s->node[i], 30);
        fail_msg("no convergence within %d s: %s", CONVERGE_MS / 1000, v.first);
    }
    assert_true(acked > 0);
    assert_true(s->reads > 0);
    if (s->wrong_reads)
        fail_msg("%llu reads of %llu gave other contents; first: %s",
                 (unsigned long long)s->wrong_reads, (unsigned long long)s->reads,
                 s->first_wrong_read);
    if (s->read_failures)
        fail_msg("%llu reads of %llu failed; first: %s", (unsigned long long)s->read_failures,
                 (unsigned long long)s->reads, s->first_read_failure);
    if (v.leftovers)
        fail_msg("%d refused uploads still on fewer than R nodes:%s", v.leftovers,
                 v.leftover_names);

    for (int i = 0; i < NNODES; i++)
        st_daemon_down(&s->node[i], 10000);
    st_etcd_stop(&s->etcd);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(cluster_soak_kills_and_restarts),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    st_etcd_stop(&S.etcd);
    return rc;
}
