/* tests/integration/test_full_disk.c - seamtexd on a full disk: its data dir is a 4 MiB tmpfs
 * (mount(2), as root; else an 8 MiB ext4 loop file; else the test is skipped, saying why).
 *
 * Sets of ~1.3 MiB of incompressible texels are uploaded until one is refused: the refusal is
 * status IO with a message that says "No space left on device" (PROTOCOL.md, docs/daemon.md),
 * the connection stays usable, the refused set is not listed and leaves no temp file behind.
 * A COMPRESS whose result does not fit fails the same way (the job's result). Reads keep
 * working on the full disk (LIST, FETCH_OPEN of every stored set byte for byte, SAMPLE, PING).
 * DELETE frees the space: the refused upload then succeeds. A restart on the same data dir
 * shows exactly the acknowledged sets, whole. FETCH of an atlas set as PNG (written through a
 * temp file in the data dir) on a disk full to the last byte is IO, never an OK with a cut
 * file. A set whose native file is missing at a start on the full disk is served from memory
 * and the log says why. A file-size limit (RLIMIT_FSIZE, on a daemon of its own) refuses an upload with IO
 * "File too large" and the daemon lives on. UPLOAD_BEGIN refuses at once (IO, the message
 * naming the free bytes) an upload that does not fit with what is promised to the uploads in
 * progress, and an abort or a commit gives the promise back (upl35; run first, on the empty
 * disk, on a raw socket so that the uploads stay open between the steps); the same without a
 * data dir, on a daemon of its own whose $TMPDIR is on the small disk. UPLOAD_COMMIT promises
 * the set's native file the same way: a commit that would take bytes promised to another
 * upload's chunks is IO, and the other upload can write all of them (res36). A commit whose
native file passes a file-size limit goes on without it and says so (a WARN naming the set,
the file and the reason; STATS native_write_failed) and the set is served and durable
(left36). The tmpfs is unmounted in the group teardown and,
 * should the test die on an assertion, by an atexit handler.
 */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <setjmp.h>
#include <spawn.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "../common/ptx_fixture.h"
#include "../common/daemon_client.h"
#include "../common/daemon_fixture.h"
#include "../common/testdata.h"
#include "../common/wire.h"
#include "fdio.h"
#include "image_io.h"
#include "proto.h"
#include "ptex.h"
#include "set.h"

extern char **environ;

#define NBIG 8

static st_daemon D;
static stc_conn *C;
static int MOUNTED;
static char HOW[64] = "";          /* "tmpfs 4m" or "ext4 loop 8m" */
static char SKIP_WHY[300] = "";
static void *BIG[NBIG];
static size_t BIGLEN[NBIG];
static int STORED[NBIG];           /* 1 when big-<i> was acknowledged and not deleted */

static void unmount_now(void)
{
    if (MOUNTED) {
        if (umount2(D.datadir, MNT_DETACH) != 0)
            fprintf(stderr, "umount %s: %s\n", D.datadir, strerror(errno));
        MOUNTED = 0;
    }
}

static void at_exit(void)
{
    if (D.pid)
        st_daemon_kill(&D);
    unmount_now();
}

static int run(const char *const *argv)
{
    pid_t pid;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    int rc = posix_spawnp(&pid, argv[0], &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc)
        return -1;
    int st;
    if (waitpid(pid, &st, 0) != pid)
        return -1;
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Mounts a small file system on D.datadir; 0, or -1 with SKIP_WHY set. */
static int mount_small(void)
{
    if (mkdir(D.datadir, 0700) != 0 && errno != EEXIST)
        return -1;
    if (mount("none", D.datadir, "tmpfs", 0, "size=4m,mode=0700") == 0) {
        snprintf(HOW, sizeof HOW, "tmpfs 4 MiB");
        return MOUNTED = 1, 0;
    }
    int merr = errno;
    char img[400];
    snprintf(img, sizeof img, "%s/disk.img", D.dir);
    int fd = open(img, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    if (fd >= 0 && ftruncate(fd, 8 << 20) == 0) {
        close(fd);
        const char *mkfs[] = {"mkfs.ext4", "-q", "-F", img, NULL};
        const char *mnt[] = {"mount", "-o", "loop", img, D.datadir, NULL};
        if (run(mkfs) == 0 && run(mnt) == 0) {
            snprintf(HOW, sizeof HOW, "ext4 loop file 8 MiB");
            return MOUNTED = 1, 0;
        }
    } else if (fd >= 0) {
        close(fd);
    }
    snprintf(SKIP_WHY, sizeof SKIP_WHY, "cannot mount a small file system (tmpfs: %s; an ext4 "
             "loop file did not work either): needs root or CAP_SYS_ADMIN", strerror(merr));
    return -1;
}

/* ~1.3 MiB .ptx of random texels (zip cannot shrink them): four 256x256 RGBA8 faces. */
static void *make_big(unsigned seed, size_t *len)
{
    st_set *s = st_fixture_rgba8_faces(256);
    if (!s)
        return NULL;
    st_error e;
    st_error_clear(&e);
    uint64_t x = 0x9E3779B97F4A7C15ull * (seed + 1);
    for (size_t i = 0; i < s->texel_bytes; i++) {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        s->texels[i] = (uint8_t)(x >> 24);
    }
    st_set_build_mips(s, UINT32_MAX);
    void *buf = NULL;
    if (st_ptex_write_mem(s, &buf, len, &e) != 0)
        buf = NULL;
    st_set_free(s);
    return buf;
}

static int upload(int i)
{
    char name[32];
    snprintf(name, sizeof name, "big-%d", i);
    stc_upload_opts o = {.hint = "ptx"};
    stc_upload_result r;
    int rc = stc_upload_buffer(C, BIG[i], BIGLEN[i], name, &o, &r);
    if (rc == 0)
        STORED[i] = 1;
    return rc;
}

static int fetch_same(int i)
{
    char name[32], path[400];
    snprintf(name, sizeof name, "big-%d", i);
    snprintf(path, sizeof path, "%s/fetched.ptx", D.dir);     /* not on the small disk */
    int rc = stc_fetch_file(C, name, STC_FETCH_PTX, path, NULL, NULL);
    if (rc) {
        fprintf(stderr, "fetch %s: %s (%s)\n", name, stc_strerror(rc), stc_errmsg(C));
        return 0;
    }
    void *got = NULL;
    size_t n = 0;
    int same = stu_read_file(path, 1u << 30, &got, &n) == 0 && n == BIGLEN[i] &&
               !memcmp(got, BIG[i], n);
    free(got);
    unlink(path);
    return same;
}

/* entries of the data dir's tmp/ (half-written uploads) */
static int tmp_entries(void)
{
    char path[400];
    snprintf(path, sizeof path, "%s/tmp", D.datadir);
    return st_test_dir_entries(path);
}

/* Everything stored is listed and fetched back whole; nothing else is listed; still serving. */
static void check_reads(void)
{
    assert_int_equal(stc_ping(C), 0);
    stc_sample_opts o = {.mode = 1, .filter = 1, .outfmt = STC_OUT_F32};
    stc_query q = {0, 0.5f, 0.5f, 0, 0, 0, 0};
    stc_sample_result r;
    assert_int_equal(stc_sample(C, "default", &o, &q, 1, &r), 0);
    const stc_set_entry *sets;
    size_t n;
    assert_int_equal(stc_list(C, &sets, &n), 0);
    int listed = 0;
    for (size_t k = 0; k < n; k++) {
        int i;
        if (sscanf(sets[k].name, "big-%d", &i) == 1) {
            assert_true(i >= 0 && i < NBIG && STORED[i]);
            listed++;
        } else if (strcmp(sets[k].name, "default") && strcmp(sets[k].name, "small") &&
                   strcmp(sets[k].name, "small-bc")) {
            fprintf(stderr, "unexpected set '%s'\n", sets[k].name);
            fail();
        }
    }
    int stored = 0;
    for (int i = 0; i < NBIG; i++)
        if (STORED[i]) {
            stored++;
            assert_true(fetch_same(i));
        }
    assert_int_equal(listed, stored);
}

static unsigned long free_kib(void)
{
    struct statvfs v;
    return statvfs(D.datadir, &v) == 0 ? (unsigned long)(v.f_bavail * v.f_frsize / 1024) : 0;
}

/* ---- UPLOAD_BEGIN's disk check, on a raw socket ---- */

static uint32_t REQID = 1;

/* Sends the frame in b (freed) and reads its reply into *r; the reply's status. */
static unsigned roundtrip(int fd, stp_buf *b, st_wire_reply *r)
{
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(b), stp_buf_avail(b)), 0);
    stp_buf_free(b);
    assert_int_equal(st_wire_read_reply(fd, r, 60000), 0);
    if (r->status) {
        size_t n = r->len < sizeof r->body ? r->len : sizeof r->body - 1;
        r->body[n] = 0;
    }
    return r->status;
}

/* UPLOAD_BEGIN of `size` bytes; the status, the upload id in *id or the message in msg. */
static unsigned begin_raw(int fd, const char *name, uint64_t size, uint32_t crc, uint64_t *id,
                          char *msg, size_t cap)
{
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(st_wire_upload_begin(&b, REQID++, name, "ptx", NULL, size, crc, 0), 0);
    st_wire_reply r;
    unsigned st = roundtrip(fd, &b, &r);
    if (st == 0)
        *id = stp_rd64(r.body);
    size_t n = st ? strlen((const char *)r.body) : 0;
    n = n < cap - 1 ? n : cap - 1;
    memcpy(msg, r.body, n);
    msg[n] = 0;
    return st;
}

static unsigned id_req(int fd, uint8_t op, uint64_t id)
{
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(stp_enc_id_req(&b, op, REQID++, 0, id), 0);
    st_wire_reply r;
    return roundtrip(fd, &b, &r);
}

static uint64_t free_bytes(void)
{
    struct statvfs v;
    assert_int_equal(statvfs(D.datadir, &v), 0);
    return (uint64_t)v.f_bavail * v.f_frsize;
}

/* A refusal at BEGIN for want of disk: IO, "No space left on device", the free bytes named
 * (at most what the test saw free a moment ago, and not far below it). */
static void assert_no_room(unsigned st, const char *msg, uint64_t seen_free)
{
    if (st != STP_S_IO)
        fail_msg("BEGIN: status %u (\"%s\"), wanted IO (%u)", st, msg, (unsigned)STP_S_IO);
    assert_non_null(strcasestr(msg, "no space left on device"));
    const char *p = strstr(msg, "does not fit: ");
    assert_non_null(p);
    unsigned long long named = 0;
    assert_int_equal(sscanf(p, "does not fit: %llu bytes free", &named), 1);
    assert_true(named <= seen_free && named + (512u << 10) >= seen_free);
}

/* Stops the daemon D and starts it again on the same data dir, C a new connection to it. */
static void restart_daemon(void)
{
    stc_close(C);
    C = NULL;
    assert_int_equal(st_daemon_stop(&D, 20000), 0);
    assert_int_equal(st_daemon_start(&D, NULL), 0);
    C = st_daemon_client(&D, NULL);
    assert_non_null(C);
}

/* The two BEGIN checks both daemons get (fd: a connection; temp_files(dir) counts the
 * uploads' temp files in dir): one BEGIN of more than is free is refused, and of two BEGINs
 * that each fit but not together the second is refused until the first is aborted. */
static void begins_that_do_not_fit(int fd, const char *what, int (*temp_files)(const char *),
                                   const char *dir)
{
    char msg[600];
    uint64_t a = 0, b = 0;
    uint64_t f = free_bytes();
    unsigned st = begin_raw(fd, "nofit", f + (1u << 20), 0, &a, msg, sizeof msg);
    printf("# %s, %llu bytes free: BEGIN of %llu bytes: %u \"%s\"\n", what,
           (unsigned long long)f, (unsigned long long)(f + (1u << 20)), st, msg);
    if (st == 0)
        id_req(fd, STP_OP_UPLOAD_ABORT, a);
    assert_no_room(st, msg, f);
    assert_int_equal(temp_files(dir), 0);
    f = free_bytes();
    uint64_t part = f * 6 / 10;
    assert_int_equal(begin_raw(fd, "part-a", part, 0, &a, msg, sizeof msg), 0);
    assert_int_equal(temp_files(dir), 1);
    st = begin_raw(fd, "part-b", part, 0, &b, msg, sizeof msg);
    if (st == 0)
        id_req(fd, STP_OP_UPLOAD_ABORT, b);
    assert_no_room(st, msg, f);
    assert_int_equal(temp_files(dir), 1);                  /* part-a's temp file only */
    assert_int_equal(id_req(fd, STP_OP_UPLOAD_ABORT, a), 0);
    assert_int_equal(begin_raw(fd, "part-b", part, 0, &b, msg, sizeof msg), 0);
    assert_int_equal(id_req(fd, STP_OP_UPLOAD_ABORT, b), 0);
    assert_int_equal(temp_files(dir), 0);
}

/* tmp_entries for begins_that_do_not_fit (the data dir's tmp/; dir unused). */
static int tmp_entries_in(const char *dir)
{
    (void)dir;
    return tmp_entries();
}

static void begin_refuses_what_the_disk_cannot_hold(void **state)
{
    (void)state;
    if (SKIP_WHY[0]) {
        printf("# SKIP %s\n", SKIP_WHY);
        skip();
    }
    int fd = st_daemon_connect(&D);
    assert_true(fd >= 0);
    begins_that_do_not_fit(fd, HOW, tmp_entries_in, NULL);
    char msg[600];
    uint64_t a = 0, b = 0;
    unsigned st;
    /* the same with a commit: while big-0 is begun, what fits beside it only is refused */
    uint64_t f = free_bytes();
    uint32_t crc = stp_crc32c(0, BIG[0], BIGLEN[0]);
    assert_int_equal(begin_raw(fd, "big-0", BIGLEN[0], crc, &a, msg, sizeof msg), 0);
    uint64_t beside = f - BIGLEN[0] / 2;
    st = begin_raw(fd, "beside", beside, 0, &b, msg, sizeof msg);
    if (st == 0)
        id_req(fd, STP_OP_UPLOAD_ABORT, b);
    assert_no_room(st, msg, f);
    stp_buf cb;
    stp_buf_init(&cb);
    stp_upload_chunk ch = {a, 0, (uint32_t)BIGLEN[0], BIG[0]};
    assert_int_equal(stp_enc_upload_chunk(&cb, REQID++, 0, &ch), 0);
    st_wire_reply r;
    assert_int_equal(roundtrip(fd, &cb, &r), 0);
    assert_int_equal(id_req(fd, STP_OP_UPLOAD_COMMIT, a), 0);
    STORED[0] = 1;
    /* committed: nothing is promised any more, what is free now can be begun */
    f = free_bytes();
    uint64_t most = f - f / 8;
    st = begin_raw(fd, "after-commit", most, 0, &b, msg, sizeof msg);
    if (st)
        fail_msg("BEGIN of %llu bytes after the commit, %llu free: %u \"%s\"",
                 (unsigned long long)most, (unsigned long long)f, st, msg);
    assert_int_equal(id_req(fd, STP_OP_UPLOAD_ABORT, b), 0);
    close(fd);
    assert_int_equal(tmp_entries(), 0);
    check_reads();
    /* the disk as test_full_disk expects it: empty of big sets */
    assert_int_equal(stc_delete(C, "big-0"), 0);
    STORED[0] = 0;
}

/* Headroom the daemon keeps free on the data disk (docs/daemon.md "Free space for uploads"). */
static uint64_t headroom_bytes(void)
{
    struct statvfs v;
    assert_int_equal(statvfs(D.datadir, &v), 0);
    uint64_t size = (uint64_t)v.f_blocks * v.f_frsize;
    return size / 64 < (64ull << 20) ? size / 64 : (64ull << 20);
}

/* UPLOAD_COMMIT writes the set's native file (about its texels' size, more than the .ptx)
 * after the body: res36 promises it against the free disk beside what UPLOAD_BEGIN promised
 * to the uploads in progress. big-0 is sent whole, then a second upload is begun of nearly
 * all the rest of the disk: committing big-0 now would take bytes promised to the second
 * one. The commit is refused (IO "... native file ... No space left on device"), big-0 is
 * not listed and leaves nothing in tmp/, and every byte of the second upload can still be
 * written. Before res36 the commit wrote its native file and the second upload failed at
 * UPLOAD_CHUNK ("write: No space left on device") though BEGIN had accepted it. Once the
 * second upload is aborted big-0 uploads and has its native file. */
static void commit_promises_the_native_file(void **state)
{
    (void)state;
    if (SKIP_WHY[0]) {
        printf("# SKIP %s\n", SKIP_WHY);
        skip();
    }
    int fd = st_daemon_connect(&D);
    assert_true(fd >= 0);
    char msg[600];
    uint64_t a = 0, b = 0;
    uint32_t crc = stp_crc32c(0, BIG[0], BIGLEN[0]);
    assert_int_equal(begin_raw(fd, "big-0", BIGLEN[0], crc, &a, msg, sizeof msg), 0);
    stp_buf cb;
    stp_buf_init(&cb);
    stp_upload_chunk ch = {a, 0, (uint32_t)BIGLEN[0], BIG[0]};
    assert_int_equal(stp_enc_upload_chunk(&cb, REQID++, 0, &ch), 0);
    st_wire_reply r;
    assert_int_equal(roundtrip(fd, &cb, &r), 0);
    /* big-0's body is on the disk; the second upload takes all but 128 KiB of the rest */
    uint64_t f = free_bytes(), keep = headroom_bytes();
    uint64_t rest = f - keep - (128u << 10);
    unsigned st = begin_raw(fd, "rest", rest, 0, &b, msg, sizeof msg);
    if (st)
        fail_msg("BEGIN of %llu bytes, %llu free: %u \"%s\"", (unsigned long long)rest,
                 (unsigned long long)f, st, msg);
    stp_buf_init(&cb);
    assert_int_equal(stp_enc_id_req(&cb, STP_OP_UPLOAD_COMMIT, REQID++, 0, a), 0);
    st = roundtrip(fd, &cb, &r);
    snprintf(msg, sizeof msg, "%.500s", st ? (const char *)r.body : "");
    printf("# %s, %llu bytes free, %llu promised to 'rest': COMMIT of big-0 (%zu bytes, its "
           "native file ~1.4 MB): %u \"%s\"\n", HOW, (unsigned long long)f,
           (unsigned long long)rest, BIGLEN[0], st, msg);
    /* every byte promised to 'rest' can be written */
    static uint8_t zeros[1u << 20];
    uint64_t off = 0;
    unsigned cst = 0;
    while (off < rest && cst == 0) {
        uint32_t n = rest - off < sizeof zeros ? (uint32_t)(rest - off) : (uint32_t)sizeof zeros;
        stp_upload_chunk c2 = {b, off, n, zeros};
        stp_buf_init(&cb);
        assert_int_equal(stp_enc_upload_chunk(&cb, REQID++, 0, &c2), 0);
        cst = roundtrip(fd, &cb, &r);
        if (cst == 0)
            off += n;
    }
    printf("# 'rest': %llu of %llu promised bytes written (chunk status %u%s%s)\n",
           (unsigned long long)off, (unsigned long long)rest, cst, cst ? ": " : "",
           cst ? (const char *)r.body : "");
    /* the disk as the tests after this one expect it, whatever the outcome */
    unsigned ast = id_req(fd, STP_OP_UPLOAD_ABORT, b);
    close(fd);
    if (st == 0)
        stc_delete(C, "big-0");
    assert_int_equal(cst, 0);
    assert_int_equal(st, STP_S_IO);
    assert_non_null(strstr(msg, "native file"));
    assert_non_null(strcasestr(msg, "no space left on device"));
    assert_int_equal(ast, 0);
    assert_int_equal(tmp_entries(), 0);   /* the refused commit left nothing behind */
    check_reads();                        /* big-0 is not listed */
    /* with the space back big-0 is committed, with its native file */
    assert_int_equal(upload(0), 0);
    char nat[400];
    snprintf(nat, sizeof nat, "%s/sets/big-0/set.native", D.datadir);
    assert_int_equal(access(nat, F_OK), 0);
    check_reads();
    assert_int_equal(stc_delete(C, "big-0"), 0);
    STORED[0] = 0;
}

/* Regular files under dir, recursively (the no-data-dir daemon's temp folder). */
static int files_under(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
            char p[1024];
            struct stat st;
            snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
            if (lstat(p, &st) == 0)
                n += S_ISDIR(st.st_mode) ? files_under(p) : 1;
        }
    closedir(d);
    return n;
}

/* Without a data dir the uploads' temp files are in the daemon's folder under $TMPDIR: the
 * same check on that file system (TMPDIR on the small disk). */
static void begin_checks_the_temp_folder_without_a_data_dir(void **state)
{
    (void)state;
    if (SKIP_WHY[0]) {
        printf("# SKIP %s\n", SKIP_WHY);
        skip();
    }
    st_daemon e;
    assert_int_equal(st_daemon_init(&e), 0);
    char base[400], *old = getenv("TMPDIR") ? strdup(getenv("TMPDIR")) : NULL;
    snprintf(base, sizeof base, "%s/nodd-tmp", D.datadir);
    assert_int_equal(mkdir(base, 0700), 0);
    setenv("TMPDIR", base, 1);   /* inherited by the daemon started below */
    const char *extra[] = {"--data-dir", "", "--no-default-set", NULL};
    int started = st_daemon_start(&e, extra);
    if (old)
        setenv("TMPDIR", old, 1);
    else
        unsetenv("TMPDIR");
    free(old);
    assert_int_equal(started, 0);
    int fd = st_daemon_connect(&e);
    assert_true(fd >= 0);
    char what[200];
    snprintf(what, sizeof what, "no data dir, TMPDIR on the %s", HOW);
    begins_that_do_not_fit(fd, what, files_under, base);
    close(fd);
    assert_int_equal(st_daemon_stop(&e, 20000), 0);
    st_daemon_cleanup(&e);
    assert_int_equal(files_under(base), 0);
    rmdir(base);
}

static void test_full_disk(void **state)
{
    (void)state;
    if (SKIP_WHY[0]) {
        printf("# SKIP %s\n", SKIP_WHY);
        skip();
    }
    /* big sets until the disk refuses one */
    int refused = -1, rc = 0;
    for (int i = 0; i < NBIG; i++) {
        rc = upload(i);
        if (rc) {
            refused = i;
            break;
        }
    }
    if (refused < 0)
        fail_msg("%d uploads of %zu bytes fit on a %s data dir", NBIG, BIGLEN[0], HOW);
    assert_true(refused >= 1);
    const char *msg = stc_errmsg(C);
    printf("# full disk (%s): upload %d of %zu bytes refused: %s \"%s\" (%lu KiB free)\n", HOW,
           refused + 1, BIGLEN[refused], stc_strerror(rc), msg, free_kib());
    assert_int_equal(rc, STC_ESERVERIO);
    assert_non_null(strcasestr(msg, "no space left on device"));
    assert_int_equal(tmp_entries(), 0);       /* the refused upload left nothing behind */
    /* reads keep working on the full disk; the connection is fine */
    check_reads();
    /* a COMPRESS whose .dds does not fit fails the same way */
    uint64_t job = 0;
    stc_job j;
    memset(&j, 0, sizeof j);
    assert_int_equal(stc_compress(C, "big-0", "big-bc", 0, 0, &job), 0);
    rc = stc_job_wait(C, job, 120000, &j);
    printf("# full disk: compress result refused: %s \"%s\"\n", stc_strerror(rc), j.message);
    if (rc == 0) {
        /* it fit after all (a BC1 set is 1/8 of the texels): not a refusal; clean up */
        assert_int_equal(stc_delete(C, "big-bc"), 0);
    } else {
        assert_int_equal(rc, STC_ESERVERIO);
        assert_non_null(strcasestr(j.message, "no space left on device"));
    }
    assert_int_equal(tmp_entries(), 0);
    check_reads();
    /* DELETE frees the space: the refused upload now fits */
    assert_int_equal(stc_delete(C, "big-0"), 0);
    STORED[0] = 0;
    rc = upload(refused);
    if (rc)
        fprintf(stderr, "upload after DELETE: %s (%s), %lu KiB free\n", stc_strerror(rc),
                stc_errmsg(C), free_kib());
    assert_int_equal(rc, 0);
    printf("# full disk: after DELETE of one set the refused upload succeeds (%lu KiB free)\n",
           free_kib());
    check_reads();
    /* a restart shows exactly the acknowledged sets, whole */
    restart_daemon();
    check_reads();
}

/* Fills the data dir's file system to the last byte with a file of its own (removed by the
 * caller); returns its path's length (0 on failure). */
static size_t fill_disk(char *path, size_t cap)
{
    snprintf(path, cap, "%s/filler", D.datadir);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0)
        return 0;
    static char block[65536];
    memset(block, 0x5a, sizeof block);
    for (size_t n = sizeof block; n > 0; n /= 2)
        while (write(fd, block, n) == (ssize_t)n)
            ;
    close(fd);
    return strlen(path);
}

/* FETCH of an atlas set as PNG goes through a temp file in the data dir's tmp/ (store/import/
 * export.c). On a full disk OpenImageIO 2.4 reported success for a PNG it could not write, and
 * FETCH_OPEN answered OK with an empty (or cut) file and its CRC: a silent wrong answer (dur28).
 * Now the export reads the file back first: IO "... No space left on device"; with space again
 * the same bytes as before. */
static void test_fetch_png_on_full_disk(void **state)
{
    (void)state;
    if (SKIP_WHY[0]) {
        printf("# SKIP %s\n", SKIP_WHY);
        skip();
    }
    /* a 256 x 256 RGB image of noise (~190 KiB as PNG), made here, uploaded as an atlas set */
    enum { W = 256 };
    unsigned char *px = malloc(W * W * 3);
    assert_non_null(px);
    unsigned x = 28u;
    for (size_t k = 0; k < W * W * 3; k++) {
        x = x * 1103515245u + 12345u;
        px[k] = (unsigned char)(x >> 16);
    }
    char src[400], ref[400], got[400], filler[400];
    snprintf(src, sizeof src, "%s/noise.png", D.dir);
    snprintf(ref, sizeof ref, "%s/ref.png", D.dir);
    snprintf(got, sizeof got, "%s/got.png", D.dir);
    st_error e;
    assert_int_equal(st_image_write(src, W, W, 3, ST_DT_U8, px, &e), 0);
    free(px);
    stc_upload_opts o = {.hint = "png"};
    stc_upload_result r;
    int rc = -1;
    for (int i = 0; i < NBIG && rc != 0; i++) {      /* make room when the disk is still full */
        rc = stc_upload_file(C, src, "pic", &o, &r);
        char big[32];
        snprintf(big, sizeof big, "big-%d", i);
        if (rc != 0 && STORED[i] && stc_delete(C, big) == 0)
            STORED[i] = 0;
    }
    assert_int_equal(rc, 0);
    assert_int_equal(stc_fetch_file(C, "pic", STC_FETCH_PNG, ref, NULL, NULL), 0);
    /* the disk full to the last byte: FETCH refuses clearly, or (never) answers the same bytes */
    assert_true(fill_disk(filler, sizeof filler) > 0);
    rc = stc_fetch_file(C, "pic", STC_FETCH_PNG, got, NULL, NULL);
    printf("# full disk: FETCH_OPEN png of an atlas set: %s \"%s\"\n", stc_strerror(rc),
           rc ? stc_errmsg(C) : "");
    if (rc == 0) {
        void *a = NULL, *b = NULL;
        size_t na = 0, nb = 0;
        assert_int_equal(stu_read_file(ref, 1u << 30, &a, &na), 0);
        assert_int_equal(stu_read_file(got, 1u << 30, &b, &nb), 0);
        int same = na == nb && !memcmp(a, b, na);
        if (!same)
            fprintf(stderr, "FETCH png on a full disk answered OK with %zu bytes, not %zu\n",
                    nb, na);
        free(a);
        free(b);
        assert_true(same);
    } else {
        assert_int_equal(rc, STC_ESERVERIO);
        assert_non_null(strcasestr(stc_errmsg(C), "no space left on device"));
    }
    assert_int_equal(tmp_entries(), 0);
    assert_int_equal(stc_ping(C), 0);
    /* space again: the same bytes as before */
    assert_int_equal(unlink(filler), 0);
    assert_int_equal(stc_fetch_file(C, "pic", STC_FETCH_PNG, got, NULL, NULL), 0);
    void *a = NULL, *b = NULL;
    size_t na = 0, nb = 0;
    assert_int_equal(stu_read_file(ref, 1u << 30, &a, &na), 0);
    assert_int_equal(stu_read_file(got, 1u << 30, &b, &nb), 0);
    assert_true(na == nb && !memcmp(a, b, na));
    free(a);
    free(b);
    assert_int_equal(stc_delete(C, "pic"), 0);
    unlink(src);
    unlink(ref);
    unlink(got);
}

/* A set whose native file is missing at start, on a full disk: it cannot be built, the set is
 * served from memory (whole: check_reads), and the log says why (pc35: before, "native file
 * could not be written: served from memory", with no reason). With space again, the next
 * start builds it. */
static void test_native_file_on_full_disk_says_why(void **state)
{
    (void)state;
    if (SKIP_WHY[0]) {
        printf("# SKIP %s\n", SKIP_WHY);
        skip();
    }
    int i = 0;
    while (i < NBIG && !STORED[i])
        i++;
    assert_true(i < NBIG);
    char nat[400], filler[400];
    snprintf(nat, sizeof nat, "%s/sets/big-%d/set.native", D.datadir, i);
    stc_close(C);
    C = NULL;
    assert_int_equal(st_daemon_stop(&D, 20000), 0);
    assert_int_equal(unlink(nat), 0);
    assert_true(fill_disk(filler, sizeof filler) > 0);
    assert_int_equal(st_daemon_start(&D, NULL), 0);
    C = st_daemon_client(&D, NULL);
    assert_non_null(C);
    check_reads();
    int why = st_daemon_log_count(&D, "No space left on device): served from memory");
    printf("# full disk: a native file that cannot be built at start: %d log line(s) with the "
           "reason\n", why);
    assert_true(why >= 1);   /* this set, and any committed without one while the disk was full */
    /* space again: the next start builds it */
    assert_int_equal(unlink(filler), 0);
    restart_daemon();
    check_reads();
    assert_int_equal(access(nat, F_OK), 0);
}

/* A file-size limit (ulimit -f, systemd LimitFSIZE=) refuses the write that passes it with
 * EFBIG; the kernel also sends SIGXFSZ, whose default action killed seamtexd at its first
 * upload or native file over the limit (dur28). Now the upload is refused with IO "File too
 * large", the daemon serves on, and with the limit lifted the same upload succeeds. Needs no
 * mount: its own daemon, the limit set on it with prlimit(2). */
static void test_file_size_limit(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, NULL), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    size_t len = 0;
    void *big = make_big(7, &len);
    assert_non_null(big);
    struct rlimit old, rl;
    assert_int_equal(prlimit(d.pid, RLIMIT_FSIZE, NULL, &old), 0);
    rl = old;
    rl.rlim_cur = 256 << 10;                   /* the soft limit: the hard one stays */
    assert_int_equal(prlimit(d.pid, RLIMIT_FSIZE, &rl, NULL), 0);
    stc_upload_opts o = {.hint = "ptx"};
    stc_upload_result r;
    int rc = stc_upload_buffer(c, big, len, "over", &o, &r);
    printf("# file-size limit 256 KiB: upload of %zu bytes: %s \"%s\"\n", len,
           stc_strerror(rc), rc ? stc_errmsg(c) : "");
    assert_int_equal(rc, STC_ESERVERIO);
    assert_non_null(strcasestr(stc_errmsg(c), "file too large"));
    assert_int_equal(stc_ping(c), 0);          /* alive, same connection */
    assert_int_equal(prlimit(d.pid, RLIMIT_FSIZE, &old, NULL), 0);
    assert_int_equal(stc_upload_buffer(c, big, len, "over", &o, &r), 0);
    stc_close(c);
    free(big);
    assert_int_equal(st_daemon_stop(&d, 20000), 0);
    st_daemon_cleanup(&d);
}

/* The size of file rel under d's data dir (-1 when absent); a set's source is found by its
 * prefix "source-". */
static long long data_file_size(const st_daemon *d, const char *set, const char *prefix)
{
    char dir[600];
    snprintf(dir, sizeof dir, "%s/sets/%s", d->datadir, set);
    DIR *dh = opendir(dir);
    if (!dh)
        return -1;
    long long size = -1;
    struct dirent *de;
    while ((de = readdir(dh)))
        if (!strncmp(de->d_name, prefix, strlen(prefix))) {
            char p[900];
            struct stat st;
            snprintf(p, sizeof p, "%s/%s", dir, de->d_name);
            if (stat(p, &st) == 0)
                size = (long long)st.st_size;
        }
    closedir(dh);
    return size;
}

static uint64_t stat_u64(stc_conn *c, const char *key)
{
    const stc_stat *st;
    size_t n;
    assert_int_equal(stc_stats(c, &st, &n), 0);
    const stc_stat *k = stc_stat_find(st, n, key);
    assert_non_null(k);
    return k->u;
}

/* A commit whose native file cannot be written although UPLOAD_COMMIT promised its room
 * (here a file-size limit that the small compressed source passes and the native file does
 * not) goes on without it, as before, but no longer silently: one WARN naming the set, the
 * file and strerror's text, and STATS native_write_failed +1 (left36). The set is served and
 * durable: after a restart it is listed and sampled, its native file rebuilt. Needs no mount
 * (its own daemon, the limit set with prlimit(2)). */
static void a_commit_without_its_native_file_says_why(void **state)
{
    (void)state;
    st_daemon d;
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, NULL), 0);
    stc_conn *c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    /* flat texels: the Ptex source compresses them, the native file keeps them as they are */
    st_set *s = st_fixture_rgba8_faces(256);
    assert_non_null(s);
    memset(s->texels, 0x5a, s->texel_bytes);
    st_set_build_mips(s, UINT32_MAX);
    void *buf = NULL;
    size_t len = 0;
    st_error e;
    st_error_clear(&e);
    assert_int_equal(st_ptex_write_mem(s, &buf, &len, &e), 0);
    st_set_free(s);
    stc_upload_opts o = {.hint = "ptx"};
    stc_upload_result r;
    assert_int_equal(stc_upload_buffer(c, buf, len, "probe", &o, &r), 0);
    long long src = data_file_size(&d, "probe", "source-");
    long long nat = data_file_size(&d, "probe", "set.native");
    printf("# source %lld bytes, native file %lld bytes\n", src, nat);
    assert_true(src > 0 && nat > 4 * src && nat > (64 << 10));
    assert_int_equal(stat_u64(c, "native_write_failed"), 0);

    struct rlimit old, rl;
    assert_int_equal(prlimit(d.pid, RLIMIT_FSIZE, NULL, &old), 0);
    rl = old;
    rl.rlim_cur = (rlim_t)(nat / 2 > 2 * src ? nat / 2 : 2 * src);
    assert_int_equal(prlimit(d.pid, RLIMIT_FSIZE, &rl, NULL), 0);
    assert_int_equal(stc_upload_buffer(c, buf, len, "nonative", &o, &r), 0);
    assert_int_equal(prlimit(d.pid, RLIMIT_FSIZE, &old, NULL), 0);
    assert_int_equal(data_file_size(&d, "nonative", "set.native"), -1);
    int warned = st_daemon_log_count(&d, "set 'nonative' committed without its native file");
    int why = st_daemon_log_count(&d, "File too large");
    int path = st_daemon_log_count(&d, ".native: writing the native file: File too large");
    printf("# native file over the file-size limit: %d WARN line(s), %d naming the reason, "
           "%d the file\n", warned, why, path);
    if (warned != 1)
        st_daemon_dump_log(&d, 20);
    assert_int_equal(warned, 1);
    assert_int_equal(path, 1);
    assert_int_equal(st_daemon_log_count(&d, "WARN  set 'nonative' committed without"), 1);
    assert_int_equal(stat_u64(c, "native_write_failed"), 1);
    stc_sample_opts so = {.mode = 1, .filter = 1, .outfmt = STC_OUT_F32};
    stc_query q = {0, 0.5f, 0.5f, 0, 0, 0, 0};
    stc_sample_result sr;
    assert_int_equal(stc_sample(c, "nonative", &so, &q, 1, &sr), 0);

    /* durable: a restart lists and samples it, and builds the missing native file */
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 20000), 0);
    assert_int_equal(st_daemon_start(&d, NULL), 0);
    c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    assert_int_equal(stc_sample(c, "nonative", &so, &q, 1, &sr), 0);
    assert_true(data_file_size(&d, "nonative", "set.native") > 0);
    assert_int_equal(stat_u64(c, "native_write_failed"), 0);
    stc_close(c);
    free(buf);
    assert_int_equal(st_daemon_stop(&d, 20000), 0);
    st_daemon_cleanup(&d);
}

static int group_setup(void **state)
{
    (void)state;
    if (st_daemon_init(&D) != 0)
        return -1;
    atexit(at_exit);
    if (mount_small() != 0)
        return 0;                                /* the test skips, saying why */
    for (int i = 0; i < NBIG; i++)
        if (!(BIG[i] = make_big((unsigned)i, &BIGLEN[i])))
            return -1;
    if (st_daemon_start(&D, NULL) != 0)
        return -1;
    C = st_daemon_client(&D, NULL);
    return C ? 0 : -1;
}

static int group_teardown(void **state)
{
    (void)state;
    if (C)
        stc_close(C);
    int st = D.pid ? st_daemon_stop(&D, 20000) : 0;
    unmount_now();
    st_daemon_cleanup(&D);
    for (int i = 0; i < NBIG; i++)
        free(BIG[i]);
    return st == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(begin_refuses_what_the_disk_cannot_hold),
        cmocka_unit_test(commit_promises_the_native_file),
        cmocka_unit_test(begin_checks_the_temp_folder_without_a_data_dir),
        cmocka_unit_test(test_full_disk),
        cmocka_unit_test(test_fetch_png_on_full_disk),
        cmocka_unit_test(test_native_file_on_full_disk_says_why),
        cmocka_unit_test(test_file_size_limit),
        cmocka_unit_test(a_commit_without_its_native_file_says_why),
    };
    return cmocka_run_group_tests_name("full_disk", tests, group_setup, group_teardown);
}
