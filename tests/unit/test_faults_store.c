/* tests/unit/test_faults_store.c - SQLite-style fault injection into the store: every
 * allocation, open, write, fsync and rename of an operation is made to fail in turn (1st, 2nd,
 * ... Nth, with ENOMEM / EIO / ENOSPC / a short write) until the operation finishes without
 * reaching the injection point, and after every run:
 *   - the status is defined: 0, ST_ENOMEM or ST_EIO (a short write must still succeed);
 *   - nothing acknowledged is lost: reopening the data dir (no injection) loads every set that
 *     was committed with status 0, with its exact bytes (manifest CRC and source CRC);
 *   - nothing half-written is visible: no set appears that was not acknowledged, tmp/ is empty
 *     after the open, broken/ stays empty, a file written atomically is the old or the new;
 *   - no leak: the binary runs under ASan in make asan (LeakSanitizer at exit).
 * Operations: the Ptex writer (mem and file), FETCH's serialisation (st_export_mem: ptx and
 * dds), the data-dir commit (new set and replace: the disk side of UPLOAD_COMMIT and of
 * COMPRESS storing its .dds), and data-dir open + load with recovery of leftovers.
 * The injection comes from tests/common/faultinject.c through -Wl,--wrap (tests/module.mk).
 * Each operation prints one "fault-table:" line (docs/daemon.md, "Fault injection").
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "bc1.h"
#include "datadir.h"
#include "export.h"
#include "fdio.h"
#include "fileio.h"
#include "import.h"
#include "ptex.h"
#include "../common/faultinject.h"
#include "../common/ptx_fixture.h"

/* ---- the loop and its tally ----------------------------------------------------------------- */

typedef struct tally {
    unsigned long counted[FI_NKINDS];
    unsigned      points;
    int           statuses[16];
    int           nstatuses;
    unsigned      lost, half;
} tally;

typedef struct fault_op {
    const char *name;
    void (*prep)(void *arg);              /* unarmed, before each run (may be NULL) */
    int  (*run)(void *arg);               /* the operation, armed */
    void (*check)(void *arg, int rc, tally *t);  /* unarmed, after each run */
    void *arg;
} fault_op;

static void note_status(tally *t, int rc)
{
    for (int i = 0; i < t->nstatuses; i++)
        if (t->statuses[i] == rc)
            return;
    if (t->nstatuses < 16)
        t->statuses[t->nstatuses++] = rc;
}

static void print_tally(const char *name, const tally *t)
{
    char st[256] = "";
    for (int i = 0; i < t->nstatuses; i++)
        snprintf(st + strlen(st), sizeof st - strlen(st), "%s%s", i ? " " : "",
                 t->statuses[i] ? st_strerror(t->statuses[i]) : "OK");
    printf("# fault-table: %-24s | calls alloc=%lu open=%lu write=%lu fsync=%lu rename=%lu | "
           "points %u | statuses %s | sets lost %u | half-written visible %u\n",
           name, t->counted[FI_ALLOC], t->counted[FI_OPEN], t->counted[FI_WRITE],
           t->counted[FI_FSYNC], t->counted[FI_RENAME], t->points, st, t->lost, t->half);
    fflush(stdout);
}

static int run_one(const fault_op *op, fi_kind k, unsigned long n, fi_how how, int *fired)
{
    if (op->prep)
        op->prep(op->arg);
    fi_arm(k, n, how, 0);
    int rc = op->run(op->arg);
    fi_disarm();
    *fired = fi_fired();
    return rc;
}

/* Every kind, every errno that fits it, N = 1.. until the operation no longer reaches N. */
static void fault_loop(const fault_op *op, unsigned kinds_mask, tally *t)
{
    for (int k = 0; k < FI_NKINDS; k++) {
        if (!(kinds_mask & (1u << k)))
            continue;
        fi_how hows[3];
        int nh = 0;
        if (k == FI_ALLOC) {
            hows[nh++] = FI_ENOMEM;
        } else {
            hows[nh++] = FI_EIO;
            hows[nh++] = FI_ENOSPC;
            if (k == FI_WRITE)
                hows[nh++] = FI_SHORT;
        }
        int fired;
        int rc = run_one(op, (fi_kind)k, 0, FI_EIO, &fired);
        unsigned long count = fi_count();
        if (rc)
            fprintf(stderr, "%s: fails without injection: %s\n", op->name, st_strerror(rc));
        assert_int_equal(rc, 0);
        op->check(op->arg, rc, t);
        if (getenv("FI_DEBUG"))
            fprintf(stderr, "%s: %s calls %lu\n", op->name, fi_kind_name((fi_kind)k), count);
        if (count > t->counted[k])
            t->counted[k] = count;
        for (int h = 0; h < nh; h++) {
            for (unsigned long n = 1;; n++) {
                rc = run_one(op, (fi_kind)k, n, hows[h], &fired);
                if (rc != 0 && rc != ST_ENOMEM && rc != ST_EIO)
                    fprintf(stderr, "%s: %s #%lu %s: status %s\n", op->name,
                            fi_kind_name((fi_kind)k), n, fi_how_name(hows[h]), st_strerror(rc));
                assert_true(rc == 0 || rc == ST_ENOMEM || rc == ST_EIO);
                if (!fired)
                    assert_int_equal(rc, 0);
                if (hows[h] == FI_SHORT)
                    assert_int_equal(rc, 0);   /* a short write is retried, never an error */
                if (k == FI_ALLOC && rc)
                    assert_int_equal(rc, ST_ENOMEM);
                op->check(op->arg, rc, t);
                note_status(t, rc);
                if (!fired)
                    break;
                t->points++;
                assert_true(n <= count + 2);   /* the operation is deterministic */
            }
        }
    }
}

#define ALL_KINDS ((1u << FI_NKINDS) - 1)

/* ---- fixtures --------------------------------------------------------------------------------- */

static char TMPDIR_[256];
static void *PTX[3];          /* default set, default set repainted, the small uniform set */
static size_t PTXLEN[3];
static st_set *PERFACE, *BC1;

static int group_setup(void **state)
{
    (void)state;
    const char *t = getenv("TMPDIR");
    snprintf(TMPDIR_, sizeof TMPDIR_, "%s/seamtex-faults-XXXXXX", t && *t ? t : "/tmp");
    if (!mkdtemp(TMPDIR_))
        return -1;
    PTX[0] = st_fixture_default_ptx(&PTXLEN[0], -1);
    PTX[1] = st_fixture_default_ptx(&PTXLEN[1], 3);
    st_error e;
    st_error_clear(&e);
    if (!PTX[0] || !PTX[1] || st_ptex_read_mem(PTX[0], PTXLEN[0], 0, &PERFACE, &e))
        return -1;
    PTX[2] = st_fixture_uniform_ptx(&PTXLEN[2]);
    st_set *us = NULL;
    int rc = PTX[2] ? st_ptex_read_mem(PTX[2], PTXLEN[2], 0, &us, &e) : -1;
    st_bc1_opts o;
    st_bc1_opts_default(&o);
    o.threads = 1;
    if (!rc)
        rc = st_bc1_compress_set(us, &o, NULL, NULL, NULL, &BC1, &e);
    st_set_free(us);
    if (rc)
        fprintf(stderr, "setup: %s\n", e.msg);
    return rc ? -1 : 0;
}

static int group_teardown(void **state)
{
    (void)state;
    free(PTX[0]);
    free(PTX[1]);
    free(PTX[2]);
    st_set_free(PERFACE);
    st_set_free(BC1);
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", TMPDIR_);
    return system(cmd) == 0 ? 0 : -1;
}

static int count_entries(const char *dir)
{
    DIR *dp = opendir(dir);
    if (!dp)
        return -1;
    int n = 0;
    struct dirent *de;
    while ((de = readdir(dp)))
        if (strcmp(de->d_name, ".") && strcmp(de->d_name, ".."))
            n++;
    closedir(dp);
    return n;
}

static int same_file(const char *path, const void *buf, size_t len)
{
    void *got = NULL;
    size_t n = 0;
    if (stu_read_file(path, 1u << 30, &got, &n) != 0)
        return 0;
    int same = n == len && !memcmp(got, buf, len);
    free(got);
    return same;
}

/* ---- serialisation: Ptex writer, export ------------------------------------------------------ */

typedef struct mem_arg {
    const st_set *set;
    int           format;   /* -1: st_ptex_write_mem, else st_export_mem's format */
    const void   *want;
    size_t        want_len;
    void         *buf;
    size_t        len;
} mem_arg;

static int mem_run(void *p)
{
    mem_arg *a = p;
    st_error e;
    st_error_clear(&e);
    if (a->format < 0)
        return st_ptex_write_mem(a->set, &a->buf, &a->len, &e);
    return st_export_mem(a->set, a->format, TMPDIR_, &a->buf, &a->len, &e);
}

static void mem_check(void *p, int rc, tally *t)
{
    mem_arg *a = p;
    if (rc == 0) {
        if (a->len != a->want_len || memcmp(a->buf, a->want, a->len) != 0)
            t->half++;
    } else if (a->buf) {
        t->half++;          /* a failed call hands out no buffer */
    }
    free(a->buf);
    a->buf = NULL;
    a->len = 0;
    assert_int_equal(t->half, 0);
}

/* st_ptex_write_mem alone is what fetch serialise (ptx) runs: see test_export_ptx_and_dds */
static void __attribute__((unused)) test_ptex_writer_mem(void **state)
{
    (void)state;
    void *want = NULL;
    size_t wl = 0;
    assert_int_equal(st_ptex_write_mem(PERFACE, &want, &wl, NULL), 0);
    mem_arg a = {PERFACE, -1, want, wl, NULL, 0};
    fault_op op = {"ptex writer (mem)", NULL, mem_run, mem_check, &a};
    tally t = {0};
    fault_loop(&op, 1u << FI_ALLOC, &t);
    print_tally(op.name, &t);
    free(want);
}

static void test_export_ptx_and_dds(void **state)
{
    (void)state;
    void *want = NULL;
    size_t wl = 0;
    tally t = {0};
    assert_int_equal(st_export_mem(PERFACE, ST_EXPORT_PTX, TMPDIR_, &want, &wl, NULL), 0);
    mem_arg a = {PERFACE, ST_EXPORT_PTX, want, wl, NULL, 0};
    fault_op op = {"fetch serialise (ptx)", NULL, mem_run, mem_check, &a};
    fault_loop(&op, ALL_KINDS, &t);
    print_tally(op.name, &t);
    free(want);

    tally t2 = {0};
    assert_int_equal(st_export_mem(BC1, ST_EXPORT_DDS, TMPDIR_, &want, &wl, NULL), 0);
    mem_arg b = {BC1, ST_EXPORT_DDS, want, wl, NULL, 0};
    fault_op op2 = {"fetch serialise (dds)", NULL, mem_run, mem_check, &b};
    fault_loop(&op2, ALL_KINDS, &t2);
    print_tally(op2.name, &t2);
    free(want);
}

typedef struct file_arg {
    char  path[512];
    const void *old, *want;
    size_t old_len, want_len;
} file_arg;

static void file_prep(void *p)
{
    file_arg *a = p;
    assert_int_equal(st_file_write_atomic(a->path, a->old, a->old_len, NULL), 0);
}

static int file_run(void *p)
{
    file_arg *a = p;
    st_error e;
    st_error_clear(&e);
    return st_ptex_write_file(PERFACE, a->path, &e);
}

static void file_check(void *p, int rc, tally *t)
{
    file_arg *a = p;
    int is_new = same_file(a->path, a->want, a->want_len);
    int is_old = same_file(a->path, a->old, a->old_len);
    char tmp[600];
    snprintf(tmp, sizeof tmp, "%s.tmp", a->path);
    if ((rc == 0 && !is_new) || (!is_new && !is_old) || access(tmp, F_OK) == 0)
        t->half++;
    assert_int_equal(t->half, 0);
}

static void test_ptex_writer_file(void **state)
{
    (void)state;
    void *want = NULL;
    size_t wl = 0;
    assert_int_equal(st_ptex_write_mem(PERFACE, &want, &wl, NULL), 0);
    file_arg a;
    snprintf(a.path, sizeof a.path, "%s/out.ptx", TMPDIR_);
    a.old = PTX[1];
    a.old_len = PTXLEN[1];
    a.want = want;
    a.want_len = wl;
    fault_op op = {"ptex writer (file)", file_prep, file_run, file_check, &a};
    tally t = {0};
    fault_loop(&op, ALL_KINDS, &t);
    print_tally(op.name, &t);
    free(want);
}

/* ---- the data dir ---------------------------------------------------------------------------- */

#define MAXSETS 4096
typedef struct model {
    char     names[MAXSETS][32];
    uint32_t crc[MAXSETS];
    int      n;
} model;

static model M;

static int model_find(const char *name)
{
    for (int i = 0; i < M.n; i++)
        if (!strcmp(M.names[i], name))
            return i;
    return -1;
}

static void model_set(const char *name, uint32_t crc)
{
    int i = model_find(name);
    if (i < 0) {
        assert_true(M.n < MAXSETS);
        i = M.n++;
        snprintf(M.names[i], sizeof M.names[i], "%s", name);
    }
    M.crc[i] = crc;
}

typedef struct seen {
    int      found[MAXSETS];
    unsigned extra, wrong;
} seen;

static int verify_cb(void *arg, const st_manifest *m, const char *source_path)
{
    seen *s = arg;
    int i = model_find(m->name);
    uint64_t bytes;
    uint32_t crc;
    if (i < 0) {
        s->extra++;
        fprintf(stderr, "set '%s' is there but was never acknowledged\n", m->name);
        return 0;
    }
    s->found[i] = 1;
    if (m->crc != M.crc[i] || st_file_crc(source_path, &bytes, &crc, NULL) || crc != m->crc) {
        s->wrong++;
        fprintf(stderr, "set '%s' does not hold its acknowledged bytes\n", m->name);
    }
    return 0;
}

/* Reopens the data dir without injection: every acknowledged set with its bytes, nothing else,
 * tmp/ empty, broken/ empty. Adds to t->lost / t->half. */
static void verify_datadir(const char *root, tally *t)
{
    st_datadir *d = NULL;
    st_error e;
    st_error_clear(&e);
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    seen *s = calloc(1, sizeof *s);
    assert_non_null(s);
    int n = st_datadir_load(d, verify_cb, s, NULL, &e);
    if (n < 0)
        fprintf(stderr, "load: %s\n", e.msg);
    assert_true(n >= 0);
    st_datadir_close(d);
    for (int i = 0; i < M.n; i++)
        if (!s->found[i]) {
            fprintf(stderr, "acknowledged set '%s' is gone\n", M.names[i]);
            t->lost++;
        }
    t->lost += s->wrong;
    t->half += s->extra;
    char p[600];
    snprintf(p, sizeof p, "%s/tmp", root);
    if (count_entries(p) != 0)
        t->half++;
    snprintf(p, sizeof p, "%s/broken", root);
    if (count_entries(p) != 0) {
        fprintf(stderr, "a set was moved to broken/\n");
        t->lost++;
    }
    free(s);
    assert_int_equal(t->lost, 0);
    assert_int_equal(t->half, 0);
}

static uint32_t crc_of(const void *p, size_t n)
{
    char path[600];
    snprintf(path, sizeof path, "%s/crc.tmp", TMPDIR_);
    assert_int_equal(st_file_write_atomic(path, p, n, NULL), 0);
    uint64_t b;
    uint32_t c;
    assert_int_equal(st_file_crc(path, &b, &c, NULL), 0);
    unlink(path);
    return c;
}

typedef struct commit_arg {
    char        root[512];
    st_datadir *d;
    char        tmp[4096];
    char        name[32];
    int         replace;       /* 1: the name "kept" again and again, else a new name each run */
    int         variant;
    int         runs;
    int         published;
    int         publish_fails; /* the publish callback returns ST_ENOMEM */
} commit_arg;

static int publish_cb(void *arg, const st_manifest *m, const char *source_path)
{
    (void)m; (void)source_path;
    commit_arg *a = arg;
    if (a->publish_fails)
        return ST_ENOMEM;
    a->published++;
    return 0;
}

static void commit_prep(void *p)
{
    commit_arg *a = p;
    st_error e;
    st_error_clear(&e);
    assert_int_equal(st_datadir_open(a->root, &a->d, &e), 0);
    int fd = -1;
    assert_int_equal(st_datadir_tmpfile(a->d, a->tmp, sizeof a->tmp, &fd, &e), 0);
    a->variant = a->runs++ & 1;
    assert_int_equal(stu_write_all(fd, PTX[a->variant], PTXLEN[a->variant]), 0);
    close(fd);
    if (a->replace)
        snprintf(a->name, sizeof a->name, "kept");
    else
        snprintf(a->name, sizeof a->name, "new-%d", a->runs);
    a->published = 0;
}

static int commit_run(void *p)
{
    commit_arg *a = p;
    st_error e;
    st_error_clear(&e);
    return st_datadir_commit(a->d, a->name, a->tmp, "ptx", "", PTXLEN[a->variant], publish_cb, a,
                             &e);
}

static void commit_check(void *p, int rc, tally *t)
{
    commit_arg *a = p;
    st_datadir_close(a->d);
    a->d = NULL;
    if (access(a->tmp, F_OK) == 0)   /* the upload file is consumed or removed either way */
        t->half++;
    assert_int_equal(a->published, rc == 0 ? 1 : 0);
    if (rc == 0)
        model_set(a->name, crc_of(PTX[a->variant], PTXLEN[a->variant]));
    verify_datadir(a->root, t);
}

static void test_datadir_commit(void **state)
{
    (void)state;
    commit_arg *a = calloc(1, sizeof *a);
    assert_non_null(a);
    snprintf(a->root, sizeof a->root, "%s/dd-commit", TMPDIR_);
    M.n = 0;
    tally t = {0};
    fault_op op = {"datadir commit (new)", commit_prep, commit_run, commit_check, a};
    fault_loop(&op, ALL_KINDS, &t);
    print_tally(op.name, &t);
    tally t2 = {0};
    a->replace = 1;
    op.name = "datadir commit (replace)";
    fault_loop(&op, ALL_KINDS, &t2);
    print_tally(op.name, &t2);
    free(a);
}

/* The publish callback failing after the commit point (the registry out of memory): the set
 * was acknowledged to nobody, so it must not be there after a restart, new or replaced (it
 * was, before datadir.c rolled the manifest back). */
static void test_datadir_commit_publish_fails(void **state)
{
    (void)state;
    commit_arg *a = calloc(1, sizeof *a);
    assert_non_null(a);
    snprintf(a->root, sizeof a->root, "%s/dd-publish", TMPDIR_);
    M.n = 0;
    tally t = {0};
    for (int replace = 0; replace < 2; replace++) {
        a->replace = replace;
        a->publish_fails = 0;
        commit_prep(a);
        assert_int_equal(commit_run(a), 0);
        commit_check(a, 0, &t);
        a->publish_fails = 1;
        commit_prep(a);
        assert_int_equal(commit_run(a), ST_ENOMEM);
        commit_check(a, ST_ENOMEM, &t);
    }
    free(a);
}

/* The same with a set (st_datadir_commit_set): its native file is renamed in before the commit
 * point, so a rollback must put the old set.native back (same file) or remove the new one. */
static void nat_commit(const char *root, const char *name, int variant, int fails, int want)
{
    commit_arg a;
    memset(&a, 0, sizeof a);
    snprintf(a.root, sizeof a.root, "%s", root);
    a.runs = variant;
    commit_prep(&a);
    snprintf(a.name, sizeof a.name, "%s", name);
    a.publish_fails = fails;
    st_error e;
    st_error_clear(&e);
    st_set *set = NULL;
    assert_int_equal(st_ptex_read_mem(PTX[a.variant], PTXLEN[a.variant], 0, &set, &e), 0);
    int rc = st_datadir_commit_set(a.d, a.name, a.tmp, "ptx", "", PTXLEN[a.variant], &set,
                                   publish_cb, &a, &e);
    assert_int_equal(rc, want);
    st_set_free(set);
    st_datadir_close(a.d);
}

static void test_datadir_commit_set_rollback(void **state)
{
    (void)state;
    char root[512], nat[1024], dir[1024];
    snprintf(root, sizeof root, "%s/dd-native-rollback", TMPDIR_);
    snprintf(nat, sizeof nat, "%s/sets/kept/" ST_DATADIR_NATIVE, root);
    nat_commit(root, "kept", 0, 0, 0);
    struct stat a, b;
    assert_int_equal(stat(nat, &a), 0);
    nat_commit(root, "kept", 1, 1, ST_ENOMEM);   /* replace, publish fails: old file back */
    assert_int_equal(stat(nat, &b), 0);
    assert_true(a.st_ino == b.st_ino && a.st_size == b.st_size);
    nat_commit(root, "fresh", 0, 1, ST_ENOMEM);  /* new, publish fails: nothing left */
    snprintf(dir, sizeof dir, "%s/sets/fresh", root);
    assert_int_equal(access(dir, F_OK), -1);
    snprintf(dir, sizeof dir, "%s/tmp", root);
    DIR *d = opendir(dir);
    assert_non_null(d);
    struct dirent *de;
    int left = 0;
    while ((de = readdir(d)))
        left += de->d_name[0] != '.';
    closedir(d);
    assert_int_equal(left, 0);                   /* no .prev / .prevnative / .native left */
}

typedef struct open_arg {
    char root[512];
} open_arg;

static void put_file(const char *root, const char *rel, const void *p, size_t n)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", root, rel);
    char *slash = strrchr(path, '/');
    *slash = 0;
    mkdir(path, 0700);
    *slash = '/';
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(p, 1, n, f), n);
    fclose(f);
}

/* What crashes leave behind: upload parts and manifest temps, a trashed set, a new set
 * without its manifest, a stray source of an interrupted replace. */
static void open_prep(void *p)
{
    open_arg *a = p;
    put_file(a->root, "tmp/x.part", PTX[0], 100);
    put_file(a->root, "tmp/y.manifest", "seamtex-set 1\n", 14);
    char trash[600];
    snprintf(trash, sizeof trash, "%s/trash/old.1", a->root);
    mkdir(trash, 0700);
    put_file(a->root, "trash/old.1/manifest", "x", 1);
    put_file(a->root, "sets/nomanifest/source-1.ptx", PTX[0], PTXLEN[0]);
    put_file(a->root, "sets/a/source-stray.ptx", PTX[1], 64);
}

static int import_cb(void *arg, const st_manifest *m, const char *source_path)
{
    (void)arg; (void)m;
    st_import_opts o;
    st_import_opts_init(&o);
    st_set *s = NULL;
    st_error e;
    st_error_clear(&e);
    int rc = st_import_file(source_path, &o, &s, &e);
    st_set_free(s);
    return rc;
}

static int open_run(void *p)
{
    open_arg *a = p;
    st_datadir *d = NULL;
    st_error e;
    st_error_clear(&e);
    int rc = st_datadir_open(a->root, &d, &e);
    if (rc)
        return rc;
    int n = st_datadir_load(d, import_cb, NULL, NULL, &e);
    st_datadir_close(d);
    return n < 0 ? n : 0;
}

static void open_check(void *p, int rc, tally *t)
{
    (void)rc;
    open_arg *a = p;
    verify_datadir(a->root, t);
    char path[700];
    snprintf(path, sizeof path, "%s/sets/nomanifest", a->root);
    if (access(path, F_OK) == 0)
        t->half++;
    snprintf(path, sizeof path, "%s/sets/a", a->root);
    if (count_entries(path) != 2)    /* manifest + its source */
        t->half++;
    assert_int_equal(t->half, 0);
}

static void test_datadir_open_and_recovery(void **state)
{
    (void)state;
    open_arg a;
    snprintf(a.root, sizeof a.root, "%s/dd-open", TMPDIR_);
    M.n = 0;
    st_datadir *d = NULL;
    assert_int_equal(st_datadir_open(a.root, &d, NULL), 0);
    static const char *const names[] = {"a", "b", "c"};
    for (int i = 0; i < 3; i++) {
        char tmp[4096];
        int fd = -1;
        assert_int_equal(st_datadir_tmpfile(d, tmp, sizeof tmp, &fd, NULL), 0);
        assert_int_equal(stu_write_all(fd, PTX[2], PTXLEN[2]), 0);   /* small: quick imports */
        close(fd);
        assert_int_equal(st_datadir_commit(d, names[i], tmp, "ptx", "", PTXLEN[2], NULL, NULL,
                                           NULL), 0);
        model_set(names[i], crc_of(PTX[2], PTXLEN[2]));
    }
    st_datadir_close(d);
    fault_op op = {"datadir open + load", open_prep, open_run, open_check, &a};
    tally t = {0};
    fault_loop(&op, ALL_KINDS, &t);
    print_tally(op.name, &t);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ptex_writer_file),
        cmocka_unit_test(test_export_ptx_and_dds),
        cmocka_unit_test(test_datadir_commit),
        cmocka_unit_test(test_datadir_commit_publish_fails),
        cmocka_unit_test(test_datadir_commit_set_rollback),
        cmocka_unit_test(test_datadir_open_and_recovery),
    };
    return cmocka_run_group_tests_name("faults_store", tests, group_setup, group_teardown);
}
