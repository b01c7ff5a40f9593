/* tests/integration/test_durability.c - seamtexd killed with SIGKILL in the middle of uploads,
 * again and again: every acknowledged set survives intact, nothing half-written appears.
 *
 * Each round: three client threads upload sets as fast as they can (new names, plus one name
 * that is replaced over and over with REPLACE), the daemon is killed with SIGKILL at a random
 * moment after the round's first acknowledged upload, restarted on the same data dir, and checked:
 *   - every set whose upload was acknowledged (in this or any earlier round) is listed;
 *   - nothing is listed that was neither acknowledged nor in flight at the kill;
 *   - the sets of this round (and an in-flight one that did land) hold what was uploaded: one
 *     per round is fetched back and its faces and every texel compared byte for byte, the
 *     others are read back texel by texel through SAMPLE (point filter, unorm8) on the face
 *     the variants differ in; the replaced name holds either its last acknowledged content
 *     or the one in flight, never a mix;
 *   - tmp/ of the data dir is empty after the restart.
 * make test runs a slice of SEAMTEX_SOAK_ROUNDS rounds (default 4); make soak runs the long
 * version: at least SEAMTEX_SOAK_ROUNDS rounds and until SEAMTEX_SOAK_SECONDS have passed. Sets
 * that have survived KEEP_ROUNDS later kills are deleted (and forgotten) so that a long soak
 * holds a bounded number of sets; a run of up to KEEP_ROUNDS + 1 rounds deletes nothing.
 * Upload data is made in-process (the built-in set written as .ptx with face 0 painted in 4
 * variants).
 */
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_fixture.h"
#include "../common/wait.h"
#include "defaultset.h"
#include "ptex.h"
#include "seamtex.h"

#define NVAR     4
#define NTHREADS 3
#define MAXNAMES 4096
#define DEFAULT_ROUNDS 4
#define KEEP_ROUNDS    16

typedef struct variant {
    void   *ptx;
    size_t  len;
    st_set *set;   /* what reading ptx gives: the reference */
} variant;

static variant V[NVAR];

typedef struct acked {
    char name[64];
    int  variant;
    int  round;
} acked;

static acked   ACK[MAXNAMES];
static size_t  NACK;
static pthread_mutex_t ACK_MU = PTHREAD_MUTEX_INITIALIZER;

/* the name replaced over and over */
static int replace_acked = -1;      /* variant of its last acknowledged upload, -1 none */

typedef struct worker {
    const st_daemon *d;
    int   round, t;
    char  inflight[64];             /* name of the upload in flight, "" none */
    int   inflight_variant;
    int   uploads;
} worker;

/* Waiting until one upload of the round has been acknowledged. */
static int one_acked(void *arg)
{
    const worker *w = arg;
    int n = 0;
    for (int t = 0; t < NTHREADS; t++)
        n += __atomic_load_n(&w[t].uploads, __ATOMIC_ACQUIRE);
    return n > 0;
}

static long env_long(const char *name, long dflt)
{
    const char *v = getenv(name);
    return v && *v ? strtol(v, NULL, 10) : dflt;
}

/* Deletes the acknowledged sets of rounds before `round` - KEEP_ROUNDS and forgets them. */
static void prune_old_rounds(stc_conn *c, int round)
{
    size_t k = 0;
    for (size_t a = 0; a < NACK; a++) {
        if (ACK[a].round < round - KEEP_ROUNDS) {
            assert_int_equal(stc_delete(c, ACK[a].name), 0);
            continue;
        }
        ACK[k++] = ACK[a];
    }
    NACK = k;
}

static int make_variants(void)
{
    for (int k = 0; k < NVAR; k++) {
        st_set *s = NULL;
        st_error e;
        if (st_default_set(&s, &e) != 0)
            return -1;
        uint8_t *t = st_face_level(s, 0, 0);
        size_t n = (size_t)s->faces[0].w * s->faces[0].h * st_texel_size(s);
        for (size_t i = 0; i < n; i++)
            t[i] = (uint8_t)(k * 61 + i * 7);
        st_set_build_mips(s, 0);
        void *buf = NULL;
        size_t len = 0;
        int rc = st_ptex_write_mem(s, &buf, &len, &e);
        st_set_free(s);
        if (rc != 0)
            return -1;
        V[k].ptx = buf;
        V[k].len = len;
        if (st_ptex_read_mem(buf, len, 0, &V[k].set, &e) != 0)
            return -1;
    }
    return 0;
}

static void record_ack(const char *name, int variant, int round)
{
    pthread_mutex_lock(&ACK_MU);
    if (NACK < MAXNAMES) {
        snprintf(ACK[NACK].name, sizeof ACK[NACK].name, "%s", name);
        ACK[NACK].variant = variant;
        ACK[NACK].round = round;
        NACK++;
    }
    pthread_mutex_unlock(&ACK_MU);
}

static void *upload_loop(void *arg)
{
    worker *w = arg;
    stc_opts o;
    memset(&o, 0, sizeof o);
    o.request_timeout_ms = 60000;
    int err;
    stc_conn *c = stc_connect_opts(w->d->host, (unsigned)w->d->port, &o, &err, NULL, 0);
    if (!c)
        return NULL;
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    uo.chunk = 128 * 1024;  /* several chunks per upload: kills land mid-upload too */
    for (int j = 0;; j++) {
        int replace = (w->t == 0 && j % 2 == 1);
        int var = (w->round + w->t + j) % NVAR;
        char name[64];
        if (replace)
            snprintf(name, sizeof name, "replaced");
        else
            snprintf(name, sizeof name, "r%02d-t%d-%03d", w->round, w->t, j);
        snprintf(w->inflight, sizeof w->inflight, "%s", name);
        w->inflight_variant = var;
        uo.flags = replace ? STC_UPLOAD_REPLACE : 0;
        stc_upload_result ur;
        int rc = stc_upload_buffer(c, V[var].ptx, V[var].len, name, &uo, &ur);
        if (rc != 0)
            break;  /* the daemon is gone: this one stays "in flight" */
        __atomic_fetch_add(&w->uploads, 1, __ATOMIC_RELEASE);
        if (replace) {
            pthread_mutex_lock(&ACK_MU);
            replace_acked = var;
            pthread_mutex_unlock(&ACK_MU);
        } else {
            record_ack(name, var, w->round);
        }
        w->inflight[0] = 0;
    }
    stc_close(c);
    return NULL;
}

static int same_as_variant(const st_set *b, int var)
{
    const st_set *a = V[var].set;
    return st_set_levels(a, NULL) == ST_OK && st_set_levels(b, NULL) == ST_OK && /* ptex.h */
           a->info.nfaces == b->info.nfaces && a->texel_bytes == b->texel_bytes &&
           !memcmp(a->faces, b->faces, (size_t)a->info.nfaces * sizeof *a->faces) &&
           !memcmp(a->texels, b->texels, a->texel_bytes);
}

/* Fetches `name` and tells which variant it is (-1 none / fetch failed). */
static int fetch_variant(stc_conn *c, const st_daemon *d, const char *name)
{
    char path[600];
    snprintf(path, sizeof path, "%s/fetch.ptx", d->dir);
    int rc = stc_fetch_file(c, name, STC_FETCH_PTX, path, NULL, NULL);
    if (rc != 0) {
        fprintf(stderr, "fetch %s: %s %s\n", name, stc_strerror(rc), stc_errmsg(c));
        return -1;
    }
    st_set *s = NULL;
    st_error e;
    if (st_ptex_read_file(path, 0, &s, &e) != 0)
        return -1;
    int found = -1;
    for (int k = 0; k < NVAR && found < 0; k++)
        if (same_as_variant(s, k))
            found = k;
    st_set_free(s);
    unlink(path);
    return found;
}

/* Identifies the variant through SAMPLE: every level-0 texel of face 0 (the face the variants
 * differ in) read with the point filter must equal the reference bit for bit; INFO must agree
 * on faces and memory. Cheaper than a FETCH (the server's Ptex writer compresses). */
static int sample_variant(stc_conn *c, const char *name)
{
    const st_set *ref = V[0].set;
    const st_face *f0 = &ref->faces[0];
    size_t n = (size_t)f0->w * f0->h;
    stc_query *q = calloc(n, sizeof *q);
    if (!q)
        return -1;
    for (uint32_t y = 0; y < f0->h; y++)
        for (uint32_t x = 0; x < f0->w; x++) {
            stc_query *p = &q[y * f0->w + x];
            p->face = 0;
            p->u = ((float)x + 0.5f) / (float)f0->w;
            p->v = ((float)y + 0.5f) / (float)f0->h;
        }
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;
    o.filter = 0;  /* point */
    o.outfmt = STC_OUT_UNORM8;
    stc_sample_result r;
    int rc = stc_sample(c, name, &o, q, n, &r);
    free(q);
    if (rc != 0 || r.count != n || r.nchan != 4) {
        fprintf(stderr, "sample %s: %s %s\n", name, stc_strerror(rc), stc_errmsg(c));
        return -1;
    }
    int found = -1;
    for (int k = 0; k < NVAR && found < 0; k++)
        if (!memcmp(r.values, st_face_level(V[k].set, 0, 0), n * 4))
            found = k;
    stc_info info;
    if (found >= 0 && (stc_info_get(c, name, 0, 0, &info) != 0 ||
                       info.nfaces != ref->info.nfaces || info.texel_bytes != ref->texel_bytes))
        found = -1;
    return found;
}

static int dir_is_empty(const char *path)
{
    DIR *dp = opendir(path);
    if (!dp)
        return 0;
    struct dirent *de;
    int n = 0;
    while ((de = readdir(dp)))
        if (strcmp(de->d_name, ".") && strcmp(de->d_name, ".."))
            n++;
    closedir(dp);
    return n == 0;
}

static void acknowledged_uploads_survive_sigkill(void **state)
{
    (void)state;
    assert_int_equal(make_variants(), 0);
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    const char *extra[] = {"--no-default-set", "--workers", "2", "--log-level", "warn", NULL};
    assert_int_equal(st_daemon_start(&d, extra), 0);
    srand((unsigned)time(NULL));
    int64_t t0 = st_now_ms();
    long want_rounds = env_long("SEAMTEX_SOAK_ROUNDS", DEFAULT_ROUNDS);
    long want_ms = env_long("SEAMTEX_SOAK_SECONDS", 0) * 1000;
    int rounds = 0, total_uploads = 0, landed_inflight = 0, fetched = 0, sampled = 0;
    for (int round = 0; round < want_rounds || st_now_ms() - t0 < want_ms; round++) {
        worker w[NTHREADS];
        pthread_t th[NTHREADS];
        for (int t = 0; t < NTHREADS; t++) {
            memset(&w[t], 0, sizeof w[t]);
            w[t].d = &d;
            w[t].round = round;
            w[t].t = t;
            assert_int_equal(pthread_create(&th[t], NULL, upload_loop, &w[t]), 0);
        }
        /* once the round has an acknowledged upload (so every round checks one), a sleep on
         * purpose: the kill lands at a random moment of the uploads still going (in a chunk,
         * a commit, an fsync, a rename), which is what this test is about */
        assert_int_equal(st_wait_until(one_acked, w, 30000), 0);
        st_sleep_ms(rand() % 400);
        st_daemon_kill(&d);
        for (int t = 0; t < NTHREADS; t++) {
            pthread_join(th[t], NULL);
            total_uploads += w[t].uploads;
        }
        int prev_replace = replace_acked;
        assert_int_equal(st_daemon_start(&d, extra), 0);
        rounds++;

        char tmp[400];
        snprintf(tmp, sizeof tmp, "%s/tmp", d.datadir);
        assert_true(dir_is_empty(tmp));

        stc_opts o;
        memset(&o, 0, sizeof o);
        o.request_timeout_ms = 60000;
        int err;
        stc_conn *c = stc_connect_opts(d.host, (unsigned)d.port, &o, &err, NULL, 0);
        assert_non_null(c);
        const stc_set_entry *sets;
        size_t n;
        assert_int_equal(stc_list(c, &sets, &n), 0);
        /* copy the names: later calls reuse the connection's buffers */
        char (*listed)[64] = calloc(n ? n : 1, sizeof *listed);
        for (size_t i = 0; i < n; i++)
            snprintf(listed[i], sizeof listed[i], "%s", sets[i].name);
        /* every acknowledged set is listed */
        for (size_t a = 0; a < NACK; a++) {
            int seen = 0;
            for (size_t i = 0; i < n && !seen; i++)
                seen = !strcmp(listed[i], ACK[a].name);
            if (!seen)
                fprintf(stderr, "round %d: acknowledged set '%s' is missing\n", round,
                        ACK[a].name);
            assert_true(seen);
        }
        /* nothing else, except what was in flight */
        for (size_t i = 0; i < n; i++) {
            int known = !strcmp(listed[i], "replaced") && (prev_replace >= 0 ||
                                                          !strcmp(w[0].inflight, "replaced"));
            for (size_t a = 0; a < NACK && !known; a++)
                known = !strcmp(listed[i], ACK[a].name);
            for (int t = 0; t < NTHREADS && !known; t++)
                if (w[t].inflight[0] && !strcmp(listed[i], w[t].inflight)) {
                    known = 1;
                    landed_inflight++;
                    /* an unacknowledged upload that landed must be complete */
                    int v = sample_variant(c, listed[i]);
                    sampled++;
                    assert_int_equal(v, w[t].inflight_variant);
                    record_ack(listed[i], v, round);  /* it exists from now on */
                }
            if (!known)
                fprintf(stderr, "round %d: unexpected set '%s'\n", round, listed[i]);
            assert_true(known);
        }
        /* this round's sets hold exactly what was uploaded (one of them fetched whole) */
        int fetched_one = 0;
        for (size_t a = 0; a < NACK; a++) {
            if (ACK[a].round != round)
                continue;
            int v;
            if (!fetched_one) {
                v = fetch_variant(c, &d, ACK[a].name);
                fetched_one = 1;
                fetched++;
            } else {
                v = sample_variant(c, ACK[a].name);
                sampled++;
            }
            if (v != ACK[a].variant)
                fprintf(stderr, "round %d: '%s' holds variant %d, uploaded %d\n", round,
                        ACK[a].name, v, ACK[a].variant);
            assert_int_equal(v, ACK[a].variant);
        }
        /* the replaced name: last acknowledged content, or the one in flight */
        int present = 0;
        for (size_t i = 0; i < n; i++)
            present |= !strcmp(listed[i], "replaced");
        if (prev_replace >= 0)
            assert_true(present);
        if (present) {
            int v = sample_variant(c, "replaced");
            sampled++;
            int inflight = !strcmp(w[0].inflight, "replaced") ? w[0].inflight_variant : -1;
            if (v != prev_replace && v != inflight)
                fprintf(stderr, "round %d: 'replaced' holds %d; acked %d, in flight %d\n",
                        round, v, prev_replace, inflight);
            assert_true(v == prev_replace || v == inflight);
            pthread_mutex_lock(&ACK_MU);
            replace_acked = v;
            pthread_mutex_unlock(&ACK_MU);
        }
        free(listed);
        prune_old_rounds(c, round);
        stc_close(c);
    }
    print_message("# %d SIGKILL rounds in %.1f s: %d acknowledged uploads, %zu sets listed, "
                  "%d fetched and %d sampled against the upload, %d unacknowledged uploads had "
                  "landed whole\n", rounds, (double)(st_now_ms() - t0) / 1000.0, total_uploads,
                  NACK, fetched, sampled, landed_inflight);
    assert_true(rounds >= want_rounds);
    assert_true(total_uploads >= rounds);  /* the test did upload between kills */
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
    for (int k = 0; k < NVAR; k++) {
        free(V[k].ptx);
        st_set_free(V[k].set);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(acknowledged_uploads_survive_sigkill),
    };
    return cmocka_run_group_tests_name("durability", tests, NULL, NULL);
}
