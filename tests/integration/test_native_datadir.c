/* tests/integration/test_native_datadir.c - native set files through the daemon's data dir:
 *   - every committed set (Ptex upload, image, mesh + texture, COMPRESS result) gets
 *     sets/<name>/set.native and is served from it; a restart maps them;
 *   - a sources-only data dir (no native files: the layout before them) is upgraded at start;
 *   - a native file with a flipped bit, a truncated one, one whose offsets lie and one that
 *     names another source are refused, moved to broken/ and rebuilt from the source, and the
 *     sets sample exactly as before;
 *   - SIGKILL while uploads (and their native writes) are in flight loses nothing acknowledged;
 *   - a daemon whose --memory-budget is smaller than one set still serves it (releasing and
 *     faulting it back), with the budget's STATS keys;
 *   - a mapped set's first sample that builds its Ptex table or atlas chart data runs on a
 *     worker, not on the I/O thread.
 */
#include <dirent.h>
#include <fcntl.h>
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/daemon_fixture.h"
#include "../common/ptx_fixture.h"
#include "../common/testdata.h"
#include "../common/wait.h"
#include "crc32c.h"
#include "native.h"
#include "seamtex.h"

static const char *const NODEF[] = {"--no-default-set", NULL};

static void upload_buf(stc_conn *c, const void *p, size_t n, const char *name)
{
    stc_upload_opts o;
    memset(&o, 0, sizeof o);
    o.hint = "ptx";
    stc_upload_result r;
    int rc = stc_upload_buffer(c, p, n, name, &o, &r);
    if (rc)
        print_message("upload %s: %d\n", name, rc);
    assert_int_equal(rc, 0);
}

static int upload_file(stc_conn *c, const char *rel, const char *name, const char *options)
{
    char path[1024];
    if (st_daemon_data_path(path, sizeof path, rel) != 0 || access(path, R_OK) != 0)
        return -1;
    stc_upload_opts o;
    memset(&o, 0, sizeof o);
    o.options = options;
    stc_upload_result r;
    int rc = stc_upload_file(c, path, name, &o, &r);
    if (rc)
        print_message("upload %s: %d\n", rel, rc);
    assert_int_equal(rc, 0);
    return 0;
}

/* n queries over faces [0, nfaces), sampled with filter; returns a copy of the floats. */
static float *sample_copy(stc_conn *c, const char *set, uint32_t nfaces, unsigned filter,
                          size_t n, size_t *nvals)
{
    stc_query *q = malloc(n * sizeof *q);
    uint32_t s = 12345;
    for (size_t i = 0; i < n; i++) {
        s = s * 1664525u + 1013904223u;
        q[i].face = (s >> 8) % nfaces;
        s = s * 1664525u + 1013904223u;
        q[i].u = (float)((s >> 8) & 0xffff) / 65536.0f;
        s = s * 1664525u + 1013904223u;
        q[i].v = (float)((s >> 8) & 0xffff) / 65536.0f;
        q[i].dudx = q[i].dvdy = (float)(i % 7) * 0.01f;
        q[i].dvdx = q[i].dudy = 0;
    }
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = 1;  /* traverse */
    o.filter = filter;
    o.outfmt = STC_OUT_F32;
    stc_sample_result r;
    int rc = stc_sample(c, set, &o, q, n, &r);
    if (rc)
        print_message("sample %s: %d\n", set, rc);
    assert_int_equal(rc, 0);
    *nvals = (size_t)r.count * r.nchan;
    float *v = malloc(*nvals * sizeof *v);
    memcpy(v, r.values, *nvals * sizeof *v);
    free(q);
    return v;
}

typedef struct ref {
    const char *name;
    uint32_t    nfaces;
    unsigned    filter;
    float      *vals;
    size_t      n;
} ref;

static void refs_take(stc_conn *c, ref *r, size_t nr)
{
    for (size_t i = 0; i < nr; i++)
        r[i].vals = sample_copy(c, r[i].name, r[i].nfaces, r[i].filter, 3000, &r[i].n);
}
static void refs_check(stc_conn *c, const ref *r, size_t nr)
{
    for (size_t i = 0; i < nr; i++) {
        size_t n;
        float *v = sample_copy(c, r[i].name, r[i].nfaces, r[i].filter, 3000, &n);
        assert_int_equal(n, r[i].n);
        assert_memory_equal(v, r[i].vals, n * sizeof *v);
        free(v);
    }
}

static int count_files(const char *dir, const char *suffix)
{
    DIR *d = opendir(dir);
    int n = 0;
    struct dirent *de;
    while (d && (de = readdir(d))) {
        size_t l = strlen(de->d_name), k = strlen(suffix);
        n += l >= k && !strcmp(de->d_name + l - k, suffix);
    }
    if (d)
        closedir(d);
    return n;
}

static void native_path(const st_daemon *d, const char *set, char *out, size_t cap)
{
    snprintf(out, cap, "%s/sets/%s/set.native", d->datadir, set);
}

static int exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0;
}

/* Flips one bit at byte `at` of the file. */
static void flip(const char *path, off_t at)
{
    int fd = open(path, O_RDWR);
    assert_true(fd >= 0);
    uint8_t b;
    assert_int_equal(pread(fd, &b, 1, at), 1);
    b ^= 0x20;
    assert_int_equal(pwrite(fd, &b, 1, at), 1);
    close(fd);
}

static void restart(st_daemon *d, const char *const *args)
{
    assert_int_equal(st_daemon_stop(d, 10000), 0);
    if (st_daemon_start(d, args) != 0) {
        st_daemon_dump_log(d, 40);
        fail();
    }
}

static void test_upgrade_corrupt_rebuild(void **st)
{
    (void)st;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, NODEF), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    size_t len;
    void *p = st_fixture_default_ptx(&len, 1);
    upload_buf(c, p, len, "p");
    free(p);
    p = st_fixture_uniform_ptx(&len);
    upload_buf(c, p, len, "q");
    free(p);
    ref r[8] = {{"p", 0, 1, NULL, 0}, {"p", 0, 12, NULL, 0}, {"q", 0, 1, NULL, 0}};
    size_t nr = 3;
    stc_info info;
    memset(&info, 0, sizeof info);
    for (size_t i = 0; i < nr; i++) {
        assert_int_equal(stc_info_get(c, r[i].name, 0, 0, &info), 0);
        r[i].nfaces = info.nfaces;
    }
    /* a COMPRESS result (BC1, stored as .dds) */
    uint64_t job = 0;
    assert_int_equal(stc_compress(c, "p", "pbc", 1, 0, &job), 0);
    stc_job jr;
    assert_int_equal(stc_job_wait(c, job, 60000, &jr), 0);
    r[nr++] = (ref){"pbc", r[0].nfaces, 1, NULL, 0};
    /* shared data when there: an image and a mesh with its texture */
    uint64_t nsets = nr - 1;  /* p is sampled twice */
    if (upload_file(c, "images/brick.png", "brick", NULL) == 0) {
        r[nr++] = (ref){"brick", 1, 2, NULL, 0};
        nsets++;
    }
    if (upload_file(c, "meshes/duck/DuckCM.png", "ducktex", NULL) == 0 &&
        upload_file(c, "meshes/duck/Duck.obj", "duck", "texture=ducktex") == 0) {
        r[nr++] = (ref){"duck", 1, 1, NULL, 0};
        nsets += 2;
    }
    refs_take(c, r, nr);
    char np[1024];
    for (size_t i = 0; i < nr; i++) {
        native_path(&d, r[i].name, np, sizeof np);
        assert_true(exists(np));
    }
    stc_close(c);

    /* a sources-only data dir: upgraded at start */
    for (size_t i = 0; i < nr; i++) {
        native_path(&d, r[i].name, np, sizeof np);
        unlink(np);
    }
    native_path(&d, "ducktex", np, sizeof np);
    unlink(np);
    restart(&d, NODEF);
    assert_int_equal(st_wait_file_has(d.log, "native file built", 5000), 0);
    c = st_daemon_client(&d, NULL);
    refs_check(c, r, nr);
    for (size_t i = 0; i < nr; i++) {
        native_path(&d, r[i].name, np, sizeof np);
        assert_true(exists(np));
    }
    stc_close(c);

    /* a restart maps them: nothing is built */
    restart(&d, NODEF);
    assert_int_equal(st_wait_file_has(d.log, "native files built), 0 set aside", 5000), 0);

    /* refused native files: a flipped bit (face table), truncated, offsets that lie */
    native_path(&d, "p", np, sizeof np);
    flip(np, 4096 + 100);
    native_path(&d, "q", np, sizeof np);
    assert_int_equal(truncate(np, 5000), 0);
    native_path(&d, "pbc", np, sizeof np);
    {
        int fd = open(np, O_RDWR);
        uint8_t h[4096];
        assert_int_equal(pread(fd, h, sizeof h, 0), 4096);
        uint64_t off = (uint64_t)1 << 40;
        memcpy(h + 1024 + 8, &off, 8);
        uint32_t crc = stu_crc32c(0, h, 4092);
        memcpy(h + 4092, &crc, 4);
        assert_int_equal(pwrite(fd, h, sizeof h, 0), 4096);
        close(fd);
    }
    char broken[1024];
    snprintf(broken, sizeof broken, "%s/broken", d.datadir);
    int before = count_files(broken, ".native");
    restart(&d, NODEF);
    assert_int_equal(st_wait_file_has(d.log, "refused", 5000), 0);
    assert_int_equal(count_files(broken, ".native"), before + 3);
    c = st_daemon_client(&d, NULL);
    refs_check(c, r, nr);
    stc_close(c);

    /* a native file that names another source (a crash between its rename and the manifest's) */
    char other[1024];
    native_path(&d, "q", other, sizeof other);
    native_path(&d, "p", np, sizeof np);
    {
        size_t n;
        void *b = st_test_read_file(other, &n);
        assert_non_null(b);
        int fd = open(np, O_WRONLY | O_TRUNC);
        assert_int_equal(write(fd, b, n), (ssize_t)n);
        close(fd);
        free(b);
    }
    restart(&d, NODEF);
    assert_int_equal(st_wait_file_has(d.log, "was built from", 5000), 0);
    c = st_daemon_client(&d, NULL);
    refs_check(c, r, nr);
    assert_int_equal(st_conn_stat(c, "sets"), nsets);
    stc_close(c);
    for (size_t i = 0; i < nr; i++)
        free(r[i].vals);
    assert_int_equal(st_daemon_down(&d, 10000), 0);
}

/* ---- SIGKILL during native writes --------------------------------------------------------- */

typedef struct killer {
    st_daemon *d;
    void      *ptx;
    size_t     len;
    int        round;
    char       acked[512][32];
    int        nacked;
} killer;

static void *uploader(void *arg)
{
    killer *k = arg;
    stc_conn *c = st_daemon_client(k->d, NULL);
    if (!c)
        return NULL;
    for (int i = 0; i < 200; i++) {
        char name[32];
        snprintf(name, sizeof name, "k%d_%d", k->round, i);
        stc_upload_opts o;
        memset(&o, 0, sizeof o);
        o.hint = "ptx";
        stc_upload_result r;
        if (stc_upload_buffer(c, k->ptx, k->len, name, &o, &r) != 0)
            break;
        if (k->nacked < 512)
            snprintf(k->acked[k->nacked++], 32, "%s", name);
    }
    stc_close(c);
    return NULL;
}

static void test_kill_during_native_writes(void **st)
{
    (void)st;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, NODEF), 0);
    static killer k;
    memset(&k, 0, sizeof k);
    k.d = &d;
    k.ptx = st_fixture_default_ptx(&k.len, 2);
    stc_conn *c = st_daemon_client(&d, NULL);
    upload_buf(c, k.ptx, k.len, "ref");
    ref r = {"ref", 0, 1, NULL, 0};
    stc_info info;
    assert_int_equal(stc_info_get(c, "ref", 0, 0, &info), 0);
    r.nfaces = info.nfaces;
    refs_take(c, &r, 1);
    stc_close(c);
    uint32_t seed = (uint32_t)getpid();
    for (int round = 0; round < 3; round++) {
        k.round = round;
        int had = k.nacked;
        pthread_t th;
        uint64_t base = st_daemon_stat(&d, "uploads_committed");
        assert_int_equal(pthread_create(&th, NULL, uploader, &k), 0);
        assert_int_equal(st_wait_stat(&d, NULL, "uploads_committed", ST_STAT_GE, base + 2,
                                      20000), 0);
        seed = seed * 1664525u + 1013904223u;
        st_sleep_ms((int)(seed >> 24) % 20);
        st_daemon_kill(&d);
        pthread_join(th, NULL);
        assert_true(k.nacked > had);
        assert_int_equal(st_daemon_start(&d, NODEF), 0);
        c = st_daemon_client(&d, NULL);
        assert_non_null(c);
        for (int i = 0; i < k.nacked; i++) {
            ref x = r;
            x.name = k.acked[i];
            refs_check(c, &x, 1);  /* every acknowledged set: there, same values */
            char np[1024];
            native_path(&d, k.acked[i], np, sizeof np);
            assert_true(exists(np));
        }
        stc_close(c);
        char tmp[1024];
        snprintf(tmp, sizeof tmp, "%s/tmp", d.datadir);
        assert_int_equal(count_files(tmp, ".native"), 0);
    }
    free(r.vals);
    free(k.ptx);
    assert_int_equal(st_daemon_down(&d, 10000), 0);
}

/* ---- a budget smaller than one set ---------------------------------------------------------- */

static void test_budget_smaller_than_a_set(void **st)
{
    (void)st;
    static const char *const args[] = {"--no-default-set", "--memory-budget", "8192", NULL};
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, args), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    size_t len;
    void *p = st_fixture_default_ptx(&len, 3);
    upload_buf(c, p, len, "big");
    free(p);
    ref r[2] = {{"big", 0, 1, NULL, 0}, {"big", 0, 12, NULL, 0}};  /* bilinear, ptex-bicubic */
    stc_info info;
    assert_int_equal(stc_info_get(c, "big", 0, 0, &info), 0);
    r[0].nfaces = r[1].nfaces = info.nfaces;
    refs_take(c, r, 2);
    assert_true(st_conn_stat(c, "stored_bytes") > 8192);
    assert_int_equal(st_conn_stat(c, "memory_budget"), 8192);
    for (int i = 0; i < 4; i++) {
        uint64_t rel = st_conn_stat(c, "budget_releases");
        assert_int_equal(st_wait_stat(&d, c, "budget_releases", ST_STAT_GE, rel + 1, 10000), 0);
        refs_check(c, r, 2);   /* served from a released mapping: faults back in */
    }
    assert_true(st_conn_stat(c, "cold_batches") >= 1);
    assert_true(st_conn_stat(c, "resident_bytes") != UINT64_MAX);
    assert_true(st_conn_stat(c, "major_faults") != UINT64_MAX);
    assert_true(st_conn_stat(c, "cold_first_us_inf") != UINT64_MAX);
    stc_close(c);
    free(r[0].vals);
    free(r[1].vals);
    assert_int_equal(st_daemon_down(&d, 10000), 0);
}

/* 16 queries at face 0 of set in mode and filter; the call's status */
static int sample_small(stc_conn *c, const char *set, unsigned mode, unsigned filter)
{
    stc_query q[16];
    for (int i = 0; i < 16; i++)
        q[i] = (stc_query){.face = 0, .u = 0.03f + 0.06f * (float)i, .v = 0.5f, .dudx = 0.02f,
                           .dvdy = 0.02f};
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = mode;
    o.filter = filter;
    o.outfmt = STC_OUT_F32;
    stc_sample_result r;
    return stc_sample(c, set, &o, q, 16, &r);
}

/* A set mapped from its native file builds its Ptex table (and an atlas its chart data) on
 * the first sample that needs it, which can take a large set hundreds of milliseconds: such
 * a first batch, however small, runs on a worker, not on the I/O thread that holds other
 * connections (dispatch.h, STS_DEFER); the batches after it, and those that need no build,
 * run inline. */
static void test_lazy_builds_run_on_a_worker(void **st)
{
    (void)st;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, NODEF), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    size_t len;
    void *p = st_fixture_default_ptx(&len, 3);
    upload_buf(c, p, len, "big");
    free(p);
    int atlas = upload_file(c, "meshes/duck/DuckCM.png", "ducktex", NULL) == 0 &&
                upload_file(c, "meshes/duck/Duck.obj", "duck", "texture=ducktex") == 0;
    stc_close(c);
    restart(&d, NODEF);   /* mapped: no table, no chart data built */
    c = st_daemon_client(&d, NULL);
    struct { const char *set; unsigned mode, filter; int to_worker; } rows[] = {
        {"big", 1, 1, 0},    /* bilinear Traverse: no table needed */
        {"big", 1, 12, 1},   /* ptex-bicubic: builds the table, on a worker */
        {"big", 1, 12, 0},   /* built: inline */
        {"big", 2, 11, 0},   /* any Ptex filter now: inline */
        {"duck", 2, 1, 0},   /* Clamp on an atlas: no chart data needed */
        {"duck", 0, 1, 1},   /* chart Discard: builds the chart data, on a worker */
        {"duck", 1, 1, 0},   /* chart Traverse, built: inline */
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        if (!atlas && !strcmp(rows[i].set, "duck"))
            continue;
        uint64_t w = st_conn_stat(c, "worker_tasks");
        int rc = sample_small(c, rows[i].set, rows[i].mode, rows[i].filter);
        if (rc)
            fail_msg("row %zu: sample of %s: %d", i, rows[i].set, rc);
        uint64_t w2 = st_conn_stat(c, "worker_tasks");
        if (w2 != w + (uint64_t)rows[i].to_worker)
            fail_msg("row %zu (%s, mode %u, filter %u): worker_tasks %llu -> %llu, want +%d", i,
                     rows[i].set, rows[i].mode, rows[i].filter, (unsigned long long)w,
                     (unsigned long long)w2, rows[i].to_worker);
    }
    if (!atlas)
        print_message("(no shared data: the atlas rows were skipped)\n");
    stc_close(c);
    assert_int_equal(st_daemon_down(&d, 10000), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_upgrade_corrupt_rebuild),
        cmocka_unit_test(test_kill_during_native_writes),
        cmocka_unit_test(test_budget_smaller_than_a_set),
        cmocka_unit_test(test_lazy_builds_run_on_a_worker),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
