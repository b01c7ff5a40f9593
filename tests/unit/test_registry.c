/* tests/unit/test_registry.c - the named-set registry and the durable data dir, tested
 * directly (no daemon): name rules, reference counting under concurrent replace/delete,
 * commit/replace/delete/load, and the crash leftovers the loader must clean or set aside.
 */
#include <pthread.h>
#include <sched.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <ftw.h>

#include <cmocka.h>

#include "datadir.h"
#include "registry.h"
#include "../common/testdata.h"

static st_set *tiny_set(uint32_t w)
{
    st_set_info info;
    memset(&info, 0, sizeof info);
    info.nfaces = 1;
    info.nchan = 1;
    info.dtype = ST_DT_U8;
    info.alpha_chan = -1;
    st_face_desc fd;
    memset(&fd, 0, sizeof fd);
    fd.w = fd.h = w;
    for (int e = 0; e < 4; e++)
        fd.adjface[e] = -1;
    st_set *s = NULL;
    st_error e;
    int rc = st_set_create(&info, &fd, 0, &s, &e);
    if (rc)
        fprintf(stderr, "st_set_create %ux%u: %s\n", w, w, e.msg);
    assert_int_equal(rc, 0);
    return s;
}

static void set_names_follow_one_rule(void **state)
{
    (void)state;
    static const struct { const char *name; int ok; } rows[] = {
        {"default", 1}, {"a", 1}, {"A-b_c.9", 1}, {"x..y", 1},
        {"", 0}, {".", 0}, {"..", 0}, {".hidden", 0}, {"a/b", 0}, {"../etc", 0},
        {"a b", 0}, {"a\\b", 0}, {"caf\xc3\xa9", 0}, {"tab\t", 0},
        {"0123456789012345678901234567890123456789012345678901234567890123", 1},   /* 64 */
        {"01234567890123456789012345678901234567890123456789012345678901234", 1},  /* 65 */
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        st_error e;
        st_error_clear(&e);
        int rc = st_name_check(rows[i].name, strlen(rows[i].name), &e);
        if ((rc == 0) != rows[i].ok)
            fprintf(stderr, "name '%s': rc %d (%s)\n", rows[i].name, rc, e.msg);
        assert_int_equal(rc == 0, rows[i].ok);
        if (!rows[i].ok) {
            assert_int_equal(rc, ST_EINVAL);   /* the wire answers INVALID */
            assert_true(e.msg[0] != 0);
        }
    }
    /* an embedded NUL is refused too (length says 3) */
    assert_int_equal(st_name_check("a\0b", 3, NULL), ST_EINVAL);
    /* the limit is 255 bytes (protocol/stp_name.h), as on the wire and in the data dir */
    char big[257];
    memset(big, 'b', sizeof big);
    assert_int_equal(st_name_check(big, 255, NULL), 0);
    assert_int_equal(st_name_check(big, 256, NULL), ST_EINVAL);
}

static void readers_keep_a_replaced_set_alive(void **state)
{
    (void)state;
    st_registry *r = st_registry_create();
    assert_non_null(r);
    int replaced = -1;
    assert_int_equal(st_registry_put(r, "s", tiny_set(4), NULL, 0, &replaced, NULL), 0);
    assert_int_equal(replaced, 0);
    st_setref *a = NULL, *b = NULL;
    assert_int_equal(st_registry_get(r, "s", &a, NULL), 0);
    assert_int_equal(a->set->faces[0].w, 4);
    assert_int_equal(st_registry_put(r, "s", tiny_set(8), NULL, 0, &replaced, NULL), 0);
    assert_int_equal(replaced, 1);
    assert_int_equal(st_registry_get(r, "s", &b, NULL), 0);
    assert_int_equal(b->set->faces[0].w, 8);
    assert_true(b->gen > a->gen);
    assert_int_equal(a->set->faces[0].w, 4);  /* still readable: a holds it */
    assert_int_equal(st_registry_remove(r, "s", NULL), 0);
    assert_int_equal(st_registry_remove(r, "s", NULL), ST_ENOTFOUND);
    assert_int_equal(b->set->faces[0].w, 8);
    st_setref_release(a);
    st_setref_release(b);
    st_error e;
    assert_int_equal(st_registry_get(r, "s", &a, &e), ST_ENOTFOUND);
    assert_non_null(strstr(e.msg, "'s'"));
    /* bad names and the set cap */
    assert_int_equal(st_registry_put(r, "../x", tiny_set(2), NULL, 0, NULL, NULL), ST_EINVAL);
    assert_int_equal(st_registry_put(r, "one", tiny_set(2), NULL, 2, NULL, NULL), 0);
    assert_int_equal(st_registry_put(r, "two", tiny_set(2), NULL, 2, NULL, NULL), 0);
    assert_int_equal(st_registry_put(r, "three", tiny_set(2), NULL, 2, NULL, NULL), ST_EBUSY);
    assert_int_equal(st_registry_put(r, "two", tiny_set(2), NULL, 2, NULL, NULL), 0); /* replace */
    /* snapshot is sorted by name */
    st_setref *snap[8];
    size_t n = st_registry_snapshot(r, snap, 8);
    assert_int_equal(n, 2);
    assert_string_equal(snap[0]->name, "one");
    assert_string_equal(snap[1]->name, "two");
    for (size_t i = 0; i < n; i++)
        st_setref_release(snap[i]);
    assert_true(st_registry_memory(r) > 0);
    st_registry_free(r);
}

typedef struct race {
    st_registry *r;
    int stop;
    long reads;
} race;

static void *reader(void *arg)
{
    race *x = arg;
    while (!__atomic_load_n(&x->stop, __ATOMIC_RELAXED)) {
        st_setref *ref = NULL;
        if (st_registry_get(x->r, "hot", &ref, NULL) == 0) {
            /* the set must be whole: its texels hold its own width everywhere */
            const st_set *s = ref->set;
            uint32_t w = s->faces[0].w;
            uint8_t v = s->texels[0];
            assert_int_equal(v, (uint8_t)w);
            assert_int_equal(s->texels[(size_t)w * w - 1], (uint8_t)w);
            st_setref_release(ref);
            __atomic_fetch_add(&x->reads, 1, __ATOMIC_RELAXED);
        }
    }
    return NULL;
}

static void concurrent_readers_survive_replace_and_delete(void **state)
{
    (void)state;
    race x = {st_registry_create(), 0, 0};
    pthread_t th[3];
    for (int i = 0; i < 3; i++)
        pthread_create(&th[i], NULL, reader, &x);
    /* 3000 replacements at least, and on until the readers have read (a loaded machine may
     * not schedule them before the writer is done) */
    for (int k = 0; k < 3000 || (__atomic_load_n(&x.reads, __ATOMIC_RELAXED) < 100 &&
                                 k < 3000000); k++) {
        uint32_t w = 1u << (1 + k % 6);  /* 2..64 */
        st_set *s = tiny_set(w);
        memset(s->texels, (int)w, s->texel_bytes);
        st_registry_put(x.r, "hot", s, NULL, 0, NULL, NULL);
        if (k % 7 == 0)
            st_registry_remove(x.r, "hot", NULL);
        if (k >= 3000)
            sched_yield(); /* past the minimum: let starved readers have the lock and the CPU */
    }
    __atomic_store_n(&x.stop, 1, __ATOMIC_RELAXED);
    for (int i = 0; i < 3; i++)
        pthread_join(th[i], NULL);
    assert_true(x.reads > 0);
    st_registry_free(x.r);
}

/* ---- data dir ------------------------------------------------------------------------------- */


static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}


typedef struct loaded {
    char names[16][ST_NAME_MAX + 1];
    char formats[16][16];
    int n, reports, busy_first;
} loaded;

static int load_cb(void *arg, const st_manifest *m, const char *src)
{
    loaded *l = arg;
    FILE *f = fopen(src, "r");
    char buf[64] = "";
    if (f) {
        if (!fgets(buf, sizeof buf, f))
            buf[0] = 0;
        fclose(f);
    }
    if (!strcmp(buf, "needs-other") && l->busy_first++ == 0)
        return ST_EBUSY;  /* ask to be loaded after the others */
    if (!strcmp(buf, "bad-import"))
        return ST_EFORMAT;
    snprintf(l->names[l->n], sizeof l->names[0], "%s", m->name);
    snprintf(l->formats[l->n], sizeof l->formats[0], "%s", m->format);
    l->n++;
    return 0;
}

static void report_cb(void *arg, const char *name, const char *why)
{
    (void)name; (void)why;
    ((loaded *)arg)->reports++;
}

static int commit_text(st_datadir *d, const char *name, const char *text, const char *fmt)
{
    char path[4096];
    int fd;
    if (st_datadir_tmpfile(d, path, sizeof path, &fd, NULL) != 0)
        return -1;
    ssize_t w = write(fd, text, strlen(text));
    close(fd);
    if (w != (ssize_t)strlen(text))
        return -1;
    return st_datadir_commit(d, name, path, fmt, "opt=1", strlen(text), NULL, NULL, NULL);
}

static void datadir_commits_replaces_deletes_and_reloads(void **state)
{
    (void)state;
    char root[] = "/tmp/st-datadir-XXXXXX";
    assert_non_null(mkdtemp(root));
    st_datadir *d = NULL;
    st_error e;
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(commit_text(d, "alpha", "first", "ptx"), 0);
    assert_int_equal(commit_text(d, "alpha", "second", "ptx"), 0);   /* replace */
    assert_int_equal(commit_text(d, "beta", "needs-other", "obj"), 0);
    assert_int_equal(commit_text(d, "gamma", "bad-import", "png"), 0);
    assert_int_equal(commit_text(d, "delta", "gone soon", "exr"), 0);
    assert_int_equal(st_datadir_delete(d, "delta", NULL, NULL, NULL), 0);
    assert_int_equal(st_datadir_delete(d, "delta", NULL, NULL, NULL), ST_ENOTFOUND);
    /* refused before anything is written */
    char p[1024];
    int fd;
    assert_int_equal(st_datadir_tmpfile(d, p, sizeof p, &fd, NULL), 0);
    close(fd);
    assert_int_equal(st_datadir_commit(d, "../evil", p, "ptx", "", 0, NULL, NULL, &e), ST_EINVAL);
    assert_int_equal(st_datadir_tmpfile(d, p, sizeof p, &fd, NULL), 0);
    assert_int_equal(write(fd, "abc", 3), 3);
    close(fd);
    assert_int_equal(st_datadir_commit(d, "size", p, "ptx", "", 4, NULL, NULL, &e), ST_ECORRUPT);
    assert_int_not_equal(access(p, F_OK), 0);  /* the part was removed */
    assert_int_equal(st_datadir_tmpfile(d, p, sizeof p, &fd, NULL), 0);
    close(fd);
    assert_int_equal(st_datadir_commit(d, "fmt", p, "P/X", "", 0, NULL, NULL, &e), ST_EINVAL);
    /* one source per set after a replace */
    snprintf(p, sizeof p, "%s/sets/alpha", root);
    assert_int_equal(st_test_dir_entries(p), 2);
    st_manifest m;
    snprintf(p, sizeof p, "%s/sets/alpha/manifest", root);
    assert_int_equal(st_manifest_read(p, &m, &e), 0);
    assert_string_equal(m.name, "alpha");
    assert_int_equal(m.bytes, 6);
    assert_string_equal(m.options, "opt=1");
    st_datadir_close(d);

    /* crash leftovers */
    snprintf(p, sizeof p, "%s/tmp/99.part", root);
    write_file(p, "half an upload");
    snprintf(p, sizeof p, "%s/sets/newbie", root);
    mkdir(p, 0700);
    snprintf(p, sizeof p, "%s/sets/newbie/source-1.ptx", root);
    write_file(p, "never committed");
    snprintf(p, sizeof p, "%s/sets/alpha/source-orphan.ptx", root);
    write_file(p, "interrupted replace");
    snprintf(p, sizeof p, "%s/sets/torn", root);   /* a manifest cut short */
    mkdir(p, 0700);
    snprintf(p, sizeof p, "%s/sets/torn/manifest", root);
    write_file(p, "seamtex-set 1\nname torn\nsource s.ptx\n");

    loaded l;
    memset(&l, 0, sizeof l);
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    int n = st_datadir_load(d, load_cb, &l, report_cb, &e);
    assert_int_equal(n, 2);
    assert_int_equal(l.n, 2);
    assert_string_equal(l.names[0], "alpha");   /* beta was deferred, then loaded */
    assert_string_equal(l.names[1], "beta");
    assert_string_equal(l.formats[1], "obj");
    assert_int_equal(l.busy_first, 2);
    assert_int_equal(l.reports, 3);            /* newbie removed, gamma + torn set aside */
    snprintf(p, sizeof p, "%s/tmp", root);
    assert_int_equal(st_test_dir_entries(p), 0);
    snprintf(p, sizeof p, "%s/sets/newbie", root);
    assert_int_not_equal(access(p, F_OK), 0);
    snprintf(p, sizeof p, "%s/sets/alpha", root);
    assert_int_equal(st_test_dir_entries(p), 2);     /* orphan removed */
    snprintf(p, sizeof p, "%s/broken", root);
    assert_int_equal(st_test_dir_entries(p), 2);     /* gamma and torn, not dropped */
    snprintf(p, sizeof p, "%s/sets", root);
    assert_int_equal(st_test_dir_entries(p), 2);
    st_datadir_close(d);

    /* a flipped byte in a committed source is caught by the CRC at load */
    snprintf(p, sizeof p, "%s/sets/alpha/manifest", root);
    assert_int_equal(st_manifest_read(p, &m, &e), 0);
    snprintf(p, sizeof p, "%s/sets/alpha/%s", root, m.source);
    write_file(p, "sekond");
    memset(&l, 0, sizeof l);
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(st_datadir_load(d, load_cb, &l, report_cb, &e), 1);
    assert_string_equal(l.names[0], "beta");
    st_datadir_close(d);
    st_test_rmtree(root);
}

/* A name of the longest legal length (255 bytes, NAME_MAX of the file system) is one
 * directory entry: it commits, reloads, is set aside to broken/ and deleted through trash/,
 * whose entries "<name>.<id>" would be too long if the name were not cut there. */
static void datadir_takes_255_byte_names(void **state)
{
    (void)state;
    char root[] = "/tmp/st-datadir-XXXXXX";
    assert_non_null(mkdtemp(root));
    char a[ST_NAME_MAX + 1], b[ST_NAME_MAX + 1];
    memset(a, 'a', ST_NAME_MAX);
    a[ST_NAME_MAX] = 0;
    memcpy(b, a, sizeof b);
    b[0] = 'b';
    st_datadir *d = NULL;
    st_error e;
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(commit_text(d, a, "long one", "ptx"), 0);
    assert_int_equal(commit_text(d, a, "replaced", "ptx"), 0);
    assert_int_equal(commit_text(d, b, "bad-import", "ptx"), 0);
    st_datadir_close(d);

    loaded l;
    memset(&l, 0, sizeof l);
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(st_datadir_load(d, load_cb, &l, report_cb, &e), 1);
    assert_string_equal(l.names[0], a);
    assert_int_equal(l.reports, 1);            /* b failed its import: set aside, not lost */
    char p[8192];
    snprintf(p, sizeof p, "%s/broken", root);
    assert_int_equal(st_test_dir_entries(p), 1);
    assert_int_equal(st_datadir_delete(d, a, NULL, NULL, &e), 0);
    snprintf(p, sizeof p, "%s/sets", root);
    assert_int_equal(st_test_dir_entries(p), 0);
    snprintf(p, sizeof p, "%s/trash", root);
    assert_int_equal(st_test_dir_entries(p), 0);
    st_datadir_close(d);
    st_test_rmtree(root);
}

/* Stages text as new contents for name (st_datadir_stage); the staged id into id. */
static int stage_text(st_datadir *d, const char *name, const char *text, char *id, size_t cap)
{
    char path[4096];
    int fd;
    if (st_datadir_tmpfile(d, path, sizeof path, &fd, NULL) != 0)
        return -1;
    ssize_t w = write(fd, text, strlen(text));
    close(fd);
    if (w != (ssize_t)strlen(text))
        return -1;
    return st_datadir_stage(d, name, path, "ptx", "", strlen(text), id, cap, NULL);
}

/* bytes of set name's committed source (its manifest), -1 when there is none */
static long committed_bytes(const char *root, const char *name)
{
    char p[4096];
    st_manifest m;
    snprintf(p, sizeof p, "%s/sets/%s/manifest", root, name);
    return st_manifest_read(p, &m, NULL) == 0 ? (long)m.bytes : -1;
}

static void staged_report(void *arg, const char *id, const char *why)
{
    (void)id; (void)why;
    (*(int *)arg)++;
}

/* A staged copy (a cluster write waiting for its quorum) leaves the committed set alone until
 * it is published, survives a restart whole, is published through the commit protocol (a
 * crash in the middle of that leaves it whole too) or dropped; bad staged leftovers go to
 * broken/, a half-built one is cleaned up at open. */
static void datadir_stages_publishes_and_drops(void **state)
{
    (void)state;
    char root[] = "/tmp/st-datadir-XXXXXX";
    assert_non_null(mkdtemp(root));
    st_datadir *d = NULL;
    st_error e;
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(commit_text(d, "alpha", "old", "ptx"), 0);
    char id1[64], id2[64], id3[64];
    assert_int_equal(stage_text(d, "alpha", "newer", id1, sizeof id1), 0);
    assert_int_equal(stage_text(d, "beta", "refused", id2, sizeof id2), 0);
    assert_int_equal(committed_bytes(root, "alpha"), 3);   /* the old set is untouched */
    assert_int_equal(committed_bytes(root, "beta"), -1);
    st_datadir_close(d);

    /* a restart: a half-built stage in tmp/ goes, the staged copies stay whole */
    char p[4096];
    snprintf(p, sizeof p, "%s/tmp/1-2-3.stage", root);
    mkdir(p, 0700);
    loaded l;
    memset(&l, 0, sizeof l);
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(st_datadir_load(d, load_cb, &l, report_cb, &e), 1);   /* alpha, old */
    snprintf(p, sizeof p, "%s/tmp", root);
    assert_int_equal(st_test_dir_entries(p), 0);
    st_datadir_staged *s = NULL;
    size_t n = 0;
    int reports = 0;
    assert_int_equal(st_datadir_staged_list(d, &s, &n, staged_report, &reports, &e), 0);
    assert_int_equal(n, 2);
    int a = !strcmp(s[0].m.name, "alpha") ? 0 : 1;
    assert_string_equal(s[a].id, id1);
    assert_int_equal(s[a].m.bytes, 5);
    assert_string_equal(s[1 - a].m.name, "beta");
    assert_true(s[0].mtime_ms > 0);
    free(s);

    /* published: the new contents are the set, the staged copy is gone */
    st_manifest m;
    char src[4096];
    assert_int_equal(st_datadir_staged_read(d, id1, &m, src, sizeof src, &e), 0);
    assert_int_equal(access(src, R_OK), 0);
    assert_int_equal(st_datadir_publish_staged(d, id1, NULL, NULL, NULL, &e), 0);
    assert_int_equal(committed_bytes(root, "alpha"), 5);
    assert_int_equal(st_datadir_publish_staged(d, id1, NULL, NULL, NULL, &e), ST_ENOTFOUND);
    snprintf(p, sizeof p, "%s/sets/alpha", root);
    assert_int_equal(st_test_dir_entries(p), 2);   /* manifest + the new source */
    /* dropped: nothing of it stays */
    assert_int_equal(st_datadir_drop_staged(d, id2, &e), 0);
    assert_int_equal(st_datadir_drop_staged(d, id2, &e), ST_ENOTFOUND);
    assert_int_equal(committed_bytes(root, "beta"), -1);
    assert_int_equal(st_datadir_publish_staged(d, "../x", NULL, NULL, NULL, &e), ST_EINVAL);

    /* a staged source that no longer matches its manifest is not published */
    assert_int_equal(stage_text(d, "alpha", "third", id3, sizeof id3), 0);
    assert_int_equal(st_datadir_staged_read(d, id3, &m, src, sizeof src, &e), 0);
    write_file(src, "thirD");
    assert_int_equal(st_datadir_publish_staged(d, id3, NULL, NULL, NULL, &e), ST_ECORRUPT);
    assert_int_equal(committed_bytes(root, "alpha"), 5);
    assert_int_equal(access(src, R_OK), 0);   /* kept: the caller decides */
    assert_int_equal(st_datadir_drop_staged(d, id3, &e), 0);

    /* a crash in the middle of a publish (its hard link in tmp/, the new source beside the
     * old manifest): the old set loads, the staged copy is whole and publishes */
    assert_int_equal(stage_text(d, "alpha", "fourth!", id3, sizeof id3), 0);
    assert_int_equal(st_datadir_staged_read(d, id3, &m, src, sizeof src, &e), 0);
    snprintf(p, sizeof p, "%s/tmp/9-9-9.part", root);
    assert_int_equal(link(src, p), 0);
    snprintf(p, sizeof p, "%s/sets/alpha/source-9-9-9.ptx", root);
    assert_int_equal(link(src, p), 0);
    /* and a staged entry that is not one: set aside, reported */
    snprintf(p, sizeof p, "%s/staged/abc", root);
    mkdir(p, 0700);
    st_datadir_close(d);
    memset(&l, 0, sizeof l);
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(st_datadir_load(d, load_cb, &l, report_cb, &e), 1);
    assert_int_equal(committed_bytes(root, "alpha"), 5);
    assert_int_equal(st_datadir_staged_list(d, &s, &n, staged_report, &reports, &e), 0);
    assert_int_equal(n, 1);
    assert_int_equal(reports, 1);
    assert_string_equal(s[0].id, id3);
    free(s);
    snprintf(p, sizeof p, "%s/broken", root);
    assert_int_equal(st_test_dir_entries(p), 1);
    assert_int_equal(st_datadir_publish_staged(d, id3, NULL, NULL, NULL, &e), 0);
    assert_int_equal(committed_bytes(root, "alpha"), 7);
    snprintf(p, sizeof p, "%s/staged", root);
    assert_int_equal(st_test_dir_entries(p), 0);
    st_datadir_close(d);
    st_test_rmtree(root);
}

/* Loads root as a process that may not read what root can (uid/gid 65534 when run as root,
 * after handing it the tree; else this process): the count of sets loaded, or a negative
 * code; *reports gets the loader's reports. Runs in a child so the test keeps its uid. */
static int load_as_user(const char *root, int *reports, const char *del, int *del_rc)
{
    int pfd[2];
    if (pipe(pfd) != 0)
        return -1000;
    pid_t pid = fork();
    if (pid == 0) {
        close(pfd[0]);
        if (geteuid() == 0) {
            char cmd[512];
            snprintf(cmd, sizeof cmd, "chown -R 65534:65534 '%s'", root);
            if (system(cmd) != 0 || setgid(65534) != 0 || setuid(65534) != 0)
                _exit(3);
        }
        loaded l;
        memset(&l, 0, sizeof l);
        st_datadir *d = NULL;
        st_error e;
        int res[3] = {-2000, 0, 0};
        if (st_datadir_open(root, &d, &e) == 0) {
            res[0] = st_datadir_load(d, load_cb, &l, report_cb, &e);
            res[1] = l.reports;
            if (del)  /* a set not loaded is not deleted blind either */
                res[2] = st_datadir_delete(d, del, NULL, NULL, &e);
            st_datadir_close(d);
        }
        ssize_t w = write(pfd[1], res, sizeof res);
        _exit(w == (ssize_t)sizeof res ? 0 : 4);
    }
    close(pfd[1]);
    int res[3] = {-3000, 0, 0};
    ssize_t r = read(pfd[0], res, sizeof res);
    close(pfd[0]);
    int status = 0;
    waitpid(pid, &status, 0);
    if (r != (ssize_t)sizeof res)
        return -4000;
    *reports = res[1];
    if (del_rc)
        *del_rc = res[2];
    return res[0];
}

/* Damage an operator may leave in sets/ stops nothing but the set it touches (dur28): a file
 * that is not a set directory goes to broken/, a set whose source file was deleted goes to
 * broken/, a set whose directory or manifest cannot be read stays in place unloaded; the
 * other sets load, and a DELETE of the unloaded set is refused (IO) rather than removing what
 * it cannot read. Before, each of these failed the whole start (ENOTDIR, ENOENT and EACCES
 * were taken for a failing disk). */
static void datadir_load_survives_stray_and_unreadable_entries(void **state)
{
    (void)state;
    char root[] = "/tmp/st-datadir-XXXXXX";
    assert_non_null(mkdtemp(root));
    st_datadir *d = NULL;
    st_error e;
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(commit_text(d, "good", "fine", "ptx"), 0);
    assert_int_equal(commit_text(d, "nosource", "to be deleted by hand", "ptx"), 0);
    assert_int_equal(commit_text(d, "closeddir", "mode 000 dir", "ptx"), 0);
    assert_int_equal(commit_text(d, "closedman", "mode 000 manifest", "ptx"), 0);
    st_datadir_close(d);
    char p[1024];
    snprintf(p, sizeof p, "%s/sets/junk", root);           /* an operator's note */
    write_file(p, "not a set");
    st_manifest m;
    snprintf(p, sizeof p, "%s/sets/nosource/manifest", root);
    assert_int_equal(st_manifest_read(p, &m, &e), 0);
    snprintf(p, sizeof p, "%s/sets/nosource/%s", root, m.source);
    assert_int_equal(unlink(p), 0);

    /* the stray file and the missing source, as whoever runs the test */
    chmod(root, 0755);
    loaded l;
    memset(&l, 0, sizeof l);
    assert_int_equal(st_datadir_open(root, &d, &e), 0);
    assert_int_equal(st_datadir_load(d, load_cb, &l, report_cb, &e), 3);
    assert_int_equal(l.reports, 2);
    st_datadir_close(d);
    snprintf(p, sizeof p, "%s/broken", root);
    assert_int_equal(st_test_dir_entries(p), 2);                 /* junk and nosource, kept */
    snprintf(p, sizeof p, "%s/sets", root);
    assert_int_equal(st_test_dir_entries(p), 3);

    /* unreadable: left in place, the others load */
    snprintf(p, sizeof p, "%s/sets/closeddir", root);
    assert_int_equal(chmod(p, 0), 0);
    snprintf(p, sizeof p, "%s/sets/closedman/manifest", root);
    assert_int_equal(chmod(p, 0), 0);
    int reports = 0, del_rc = 0;
    assert_int_equal(load_as_user(root, &reports, "closedman", &del_rc), 1);
    assert_int_equal(reports, 2);
    assert_int_equal(del_rc, ST_EIO);   /* its manifest cannot be read: not deleted */
    snprintf(p, sizeof p, "%s/sets", root);
    assert_int_equal(st_test_dir_entries(p), 3);                 /* nothing moved or removed */
    snprintf(p, sizeof p, "%s/broken", root);
    assert_int_equal(st_test_dir_entries(p), 2);
    /* permissions put right: everything loads again */
    snprintf(p, sizeof p, "%s/sets/closeddir", root);
    assert_int_equal(chmod(p, 0700), 0);
    snprintf(p, sizeof p, "%s/sets/closedman/manifest", root);
    assert_int_equal(chmod(p, 0600), 0);
    assert_int_equal(load_as_user(root, &reports, NULL, NULL), 3);
    assert_int_equal(reports, 0);
    st_test_rmtree(root);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(set_names_follow_one_rule),
        cmocka_unit_test(readers_keep_a_replaced_set_alive),
        cmocka_unit_test(concurrent_readers_survive_replace_and_delete),
        cmocka_unit_test(datadir_commits_replaces_deletes_and_reloads),
        cmocka_unit_test(datadir_takes_255_byte_names),
        cmocka_unit_test(datadir_stages_publishes_and_drops),
        cmocka_unit_test(datadir_load_survives_stray_and_unreadable_entries),
    };
    return cmocka_run_group_tests_name("registry", tests, NULL, NULL);
}
