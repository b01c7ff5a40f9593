/* tests/integration/test_server_upload.c - uploads to seamtexd: upload, INFO, FETCH and
 * DELETE round trip, a wrong checksum, concurrent uploads of one name, a dropped upload resumed
 * on a new connection, kept uploads expiring, and a killed daemon's uploads without a data
 * dir removed at the next start.
 *
 * One daemon with defaults for the group, plus daemons of their own for the upload-keep
 * settings (tests/common/daemon_fixture.h), on 127.0.0.1 port 0 with temp data dirs. Upload
 * data is made in-process (tests/common/ptx_fixture.h): nothing here needs SEAMTEX_DATA.
 */
#include <ftw.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "../common/daemon_client.h"
#include "../common/ptx_fixture.h"
#include "../common/wait.h"
#include "../common/wire.h"
#include "proto.h"
#include "ptex.h"

/* the group's daemon: defaults, --heavy-batch 2048 (set in main) */
#define D1 ST_GROUP

/* ---- helpers --------------------------------------------------------------------------------- */

typedef struct racer {
    const void *ptx;
    size_t len;
    int rc;
} racer;

static void *race_upload(void *arg)
{
    racer *r = arg;
    stc_conn *c = st_daemon_client(&D1, NULL);
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

/* Begins an upload of `len` bytes on a raw socket and sends its first `part` bytes; returns
 * the socket (the caller closes it to drop the connection) and the upload id. */
static int raw_partial_upload(const st_daemon *d, const char *name, const uint8_t *data,
                              size_t len, size_t part, uint64_t *id)
{
    int fd = st_daemon_connect(d);
    assert_true(fd >= 0);
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(st_wire_upload_begin(&b, 1, name, "ptx", NULL, len, stp_crc32c(0, data, len), 0),
                     0);
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    st_wire_reply r;
    assert_int_equal(st_wire_read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, 0);
    *id = stp_rd64(r.body);
    assert_int_equal(stp_rd64(r.body + 8), 0);
    for (size_t off = 0, k = 2; off < part; k++) {
        size_t n = part - off < 65536 ? part - off : 65536;
        stp_buf_clear(&b);
        stp_upload_chunk ch = {*id, off, (uint32_t)n, data + off};
        stp_enc_upload_chunk(&b, (uint32_t)k, 0, &ch);
        assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
        assert_int_equal(st_wire_read_reply(fd, &r, 5000), 0);
        assert_int_equal(r.status, 0);
        off += n;
        assert_int_equal(stp_rd64(r.body), off);
    }
    stp_buf_free(&b);
    return fd;
}

/* One upload with RESUME; busy while the server has not yet seen the old connection close. */
typedef struct resume_try {
    stc_conn *c;
    const void *data;
    size_t len;
    const char *name;
    stc_upload_result *ur;
    int rc;
} resume_try;

static int resume_not_busy(void *arg)
{
    resume_try *t = arg;
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    uo.flags = STC_UPLOAD_RESUME;
    t->rc = stc_upload_buffer(t->c, t->data, t->len, t->name, &uo, t->ur);
    return t->rc != STC_EBUSY;
}

/* Upload with RESUME, tried again until the server has released the dropped connection's
 * upload (STC_EBUSY until then; 10 s at most). */
static int upload_resume(stc_conn *c, const void *data, size_t len, const char *name,
                         stc_upload_result *ur)
{
    resume_try t = {c, data, len, name, ur, STC_EBUSY};
    st_wait_until(resume_not_busy, &t, 10000);
    return t.rc;
}

/* ---- tests ---------------------------------------------------------------------------------- */

static void upload_info_fetch_delete_round_trip(void **state)
{
    (void)state;
    size_t len = 0;
    void *ptx = st_fixture_default_ptx(&len, 3);
    assert_non_null(ptx);
    stc_conn *c = st_daemon_client(&D1, NULL);
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
    assert_int_equal(st_set_levels(a, &e), 0); /* every level compared: made (ptex.h) */
    assert_int_equal(st_set_levels(b, &e), 0);
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

/* A .ptx whose stored reduction does not inflate imports in the library (the reader defers
 * the reductions, ptex.h) but is refused at upload, with FORMAT, as before: the daemon makes
 * the levels right after the import. */
static void upload_with_a_corrupt_stored_reduction_is_refused(void **state)
{
    (void)state;
    stc_conn *c = st_daemon_client(&D1, NULL);
    assert_non_null(c);
    for (int what = 0; what < 2; what++) {
        size_t len = 0;
        uint8_t *ptx = st_fixture_default_ptx(&len, 5);
        assert_non_null(ptx);
        assert_int_equal(st_fixture_corrupt_reduction(ptx, len, what), 0);
        st_set *s = NULL;
        st_error e;
        assert_int_equal(st_ptex_read_mem(ptx, len, 0, &s, &e), 0);
        assert_int_equal(st_set_levels(s, &e), ST_EFORMAT);
        st_set_free(s);
        stc_upload_opts uo;
        memset(&uo, 0, sizeof uo);
        uo.hint = "ptx";
        stc_upload_result ur;
        assert_int_equal(stc_upload_buffer(c, ptx, len, "badreduction", &uo, &ur), STC_EFORMAT);
        stc_info info;
        assert_int_equal(stc_info_get(c, "badreduction", 0, 0, &info), STC_ENOTFOUND);
        free(ptx);
    }
    stc_close(c);
}

static void upload_with_wrong_crc_is_corrupt(void **state)
{
    (void)state;
    int fd = st_daemon_connect(&D1);
    assert_true(fd >= 0);
    uint8_t body[512], frame[1024];
    stp_buf b;
    stp_buf_init(&b);
    assert_int_equal(st_wire_upload_begin(&b, 1, "crcbad", "ptx", NULL, 4, 0x12345678, 0), 0);
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    st_wire_reply r;
    assert_int_equal(st_wire_read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, 0);
    uint64_t id = stp_rd64(r.body);
    stp_buf_clear(&b);
    stp_upload_chunk ch = {id, 0, 4, (const uint8_t *)"abcd"};
    stp_enc_upload_chunk(&b, 2, 0, &ch);
    stp_enc_id_req(&b, STP_OP_UPLOAD_COMMIT, 3, 0, id);
    assert_int_equal(st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b)), 0);
    assert_int_equal(st_wire_read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, 0);
    assert_int_equal(stp_rd64(r.body), 4);
    assert_int_equal(st_wire_read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.reqid, 3);
    assert_int_equal(r.status, STP_S_CORRUPT);
    /* a chunk for an upload id this connection does not hold */
    stp_buf_clear(&b);
    stp_upload_chunk ch2 = {id + 1000, 0, 4, (const uint8_t *)"abcd"};
    stp_enc_upload_chunk(&b, 4, 0, &ch2);
    st_wire_send_all(fd, stp_buf_head(&b), stp_buf_avail(&b));
    assert_int_equal(st_wire_read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.status, STP_S_NOT_FOUND);
    /* a set name with a path in it */
    size_t n = stp_enc_name_req(&b, STP_OP_DELETE, 5, 0, "a") == 0 ? 0 : 0;
    (void)n;
    uint8_t nb[16] = {5, 0, '.', '.', '/', 'x', 'y'};
    size_t fl = st_wire_frame(frame, "STX1", 1, STP_OP_DELETE, 0, 6, nb, 7, 7);
    st_wire_send_all(fd, frame, fl);
    assert_int_equal(st_wire_read_reply(fd, &r, 5000), 0);
    assert_int_equal(r.reqid, 6);
    assert_int_equal(r.status, STP_S_INVALID); /* a malformed name is INVALID */
    stp_buf_free(&b);
    (void)body;
    close(fd);
}

/* A dropped connection leaves its upload kept; UPLOAD_BEGIN with RESUME on a new connection
 * continues from the bytes the server has, and the set is whole (INFO matches, CRC checked). */
static void dropped_upload_resumes_on_a_new_connection(void **state)
{
    (void)state;
    size_t len;
    uint8_t *ptx = st_fixture_default_ptx(&len, 3);
    assert_non_null(ptx);
    assert_true(len > 3 * 65536);
    uint64_t id;
    size_t part = 2 * 65536 + 1000;
    int fd = raw_partial_upload(&D1, "resumed", ptx, len, part, &id);
    uint64_t before = st_daemon_stat(&D1, "upload_bytes");
    close(fd);
    stc_conn *c = st_daemon_client(&D1, NULL);
    assert_non_null(c);
    assert_true(stc_server_info(c)->caps & STC_CAP_UPLOAD_RESUME);
    stc_upload_result ur;
    assert_int_equal(upload_resume(c, ptx, len, "resumed", &ur), 0);
    assert_int_equal(ur.resumed_from, part);
    assert_int_equal(st_daemon_stat(&D1, "upload_bytes") - before, len - part); /* only the rest sent */
    assert_true(st_daemon_stat(&D1, "uploads_resumed") >= 1);
    stc_info inf;
    assert_int_equal(stc_info_get(c, "resumed", 0, 0, &inf), 0);
    assert_int_equal(inf.nfaces, 384);
    /* a different file under another name: nothing to resume, a fresh upload */
    fd = raw_partial_upload(&D1, "resumed2", ptx, len, 65536, &id);
    close(fd);
    /* other content, so another CRC32C: the kept upload is not taken; the fresh upload of the
     * damaged file fails to import or not, either way without resuming */
    uint64_t resumed = st_daemon_stat(&D1, "uploads_resumed");
    ptx[len / 2] ^= 0x40;
    int rc = upload_resume(c, ptx, len, "resumed2", &ur);
    if (rc == 0)
        assert_int_equal(ur.resumed_from, 0);
    assert_int_equal(st_daemon_stat(&D1, "uploads_resumed"), resumed);
    ptx[len / 2] ^= 0x40;
    if (rc == 0) {
        assert_int_equal(stc_delete(c, "resumed2"), 0);
    }
    assert_int_equal(upload_resume(c, ptx, len, "resumed2", &ur), 0);
    assert_int_equal(ur.resumed_from, 65536);
    /* the connection broke while COMMIT ran (its reply lost): RESUME finds the upload done,
     * COMMIT repeats the reply, and no byte is sent again */
    before = st_daemon_stat(&D1, "upload_bytes");
    assert_int_equal(upload_resume(c, ptx, len, "resumed2", &ur), 0);
    assert_int_equal(ur.resumed_from, len);
    assert_string_equal(ur.name, "resumed2");
    assert_int_equal(ur.nfaces, 384);
    assert_int_equal(st_daemon_stat(&D1, "upload_bytes"), before);
    /* once the set is deleted that record no longer counts: a fresh upload */
    assert_int_equal(stc_delete(c, "resumed2"), 0);
    assert_int_equal(upload_resume(c, ptx, len, "resumed2", &ur), 0);
    assert_int_equal(ur.resumed_from, 0);
    stc_close(c);
    free(ptx);
}

/* Bytes of the files under a folder, and how many entries (files and folders) it holds. */
static uint64_t tree_bytes;
static int tree_entries;
static int tree_cb(const char *p, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)p;
    if (ftw->level == 0)
        return 0;
    tree_entries++;
    if (flag == FTW_F)
        tree_bytes += (uint64_t)sb->st_size;
    return 0;
}
static uint64_t tree_measure(const char *dir)
{
    tree_bytes = 0;
    tree_entries = 0;
    nftw(dir, tree_cb, 16, FTW_PHYS);
    return tree_bytes;
}

/* Without a data dir an upload in progress is a temp file under $TMPDIR (pc35). A killed
 * daemon cannot remove it: before, it stayed there for good (252 MiB from 63 uploads begun,
 * in the probe), since nothing at start could tell a dead daemon's files from a live one's.
 * Now each daemon keeps its temp files in a folder of its own, locked for its life: the next
 * start removes a dead daemon's folder and leaves a running daemon's alone; a clean stop
 * removes its own. */
static void a_killed_daemons_uploads_without_a_data_dir_go_at_the_next_start(void **state)
{
    (void)state;
    size_t len;
    uint8_t *ptx = st_fixture_default_ptx(&len, 5);
    assert_non_null(ptx);
    st_daemon a, b;
    assert_int_equal(st_daemon_init(&a), 0);
    assert_int_equal(st_daemon_init(&b), 0);
    char base[400], *old = getenv("TMPDIR") ? strdup(getenv("TMPDIR")) : NULL;
    snprintf(base, sizeof base, "%s/tmpbase", a.dir);
    assert_int_equal(mkdir(base, 0700), 0);
    setenv("TMPDIR", base, 1);   /* inherited by the daemons started below */
    const char *extra[] = {"--data-dir", "", "--no-default-set", NULL};
    assert_int_equal(st_daemon_start(&a, extra), 0);
    uint64_t id;
    int fd = raw_partial_upload(&a, "gone", ptx, len, 2 * 65536, &id);
    assert_true(tree_measure(base) >= 2 * 65536);
    st_daemon_kill(&a);
    close(fd);
    assert_true(tree_measure(base) >= 2 * 65536);   /* what the kill left */
    /* another daemon starts on the same TMPDIR: the dead one's files go */
    assert_int_equal(st_daemon_start(&b, extra), 0);
    assert_int_equal(tree_measure(base), 0);
    assert_int_equal(st_daemon_log_count(&b, "removed 1 temp folder"), 1);
    /* b's upload in progress is left alone when a starts again beside it */
    int fdb = raw_partial_upload(&b, "live", ptx, len, 2 * 65536, &id);
    assert_int_equal(st_daemon_start(&a, extra), 0);
    assert_true(tree_measure(base) >= 2 * 65536);
    close(fdb);
    stc_conn *c = st_daemon_client(&b, NULL);
    assert_non_null(c);
    stc_upload_opts uo;
    memset(&uo, 0, sizeof uo);
    uo.hint = "ptx";
    stc_upload_result ur;
    assert_int_equal(stc_upload_buffer(c, ptx, len, "whole", &uo, &ur), 0);
    stc_close(c);
    /* a clean stop removes each daemon's own folder */
    assert_int_equal(st_daemon_stop(&a, 10000), 0);
    assert_int_equal(st_daemon_stop(&b, 10000), 0);
    tree_measure(base);
    assert_int_equal(tree_entries, 0);
    if (old) {
        setenv("TMPDIR", old, 1);
        free(old);
    } else {
        unsetenv("TMPDIR");
    }
    st_daemon_cleanup(&a);
    st_daemon_cleanup(&b);
    free(ptx);
}

/* Kept uploads go after upload-keep seconds; with upload-keep 0 nothing is kept and the
 * server does not offer RESUME. */
static void kept_uploads_expire_and_can_be_turned_off(void **state)
{
    (void)state;
    size_t len;
    uint8_t *ptx = st_fixture_default_ptx(&len, 4);
    assert_non_null(ptx);
    st_daemon d;
    const char *extra[] = {"--upload-keep", "1", "--no-default-set", NULL};
    assert_int_equal(st_daemon_init(&d), 0);
    assert_int_equal(st_daemon_start(&d, extra), 0);
    uint64_t id;
    int fd = raw_partial_upload(&d, "late", ptx, len, 65536, &id);
    close(fd);
    int64_t t0 = st_now_ms();
    assert_int_equal(st_wait_stat(&d, NULL, "uploads_expired", ST_STAT_GE, 1, 10000), 0);
    assert_int_equal(st_daemon_stat(&d, "uploads_expired"), 1);
    assert_true(st_now_ms() - t0 >= 900);  /* not before upload-keep (1 s) */
    stc_conn *c = st_daemon_client(&d, NULL);
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
    c = st_daemon_client(&d, NULL);
    assert_non_null(c);
    assert_false(stc_server_info(c)->caps & STC_CAP_UPLOAD_RESUME);
    assert_int_equal(upload_resume(c, ptx, len, "gone", &ur), 0);
    assert_int_equal(ur.resumed_from, 0);
    stc_close(c);
    assert_int_equal(st_daemon_stop(&d, 10000), 0);
    st_daemon_cleanup(&d);
    free(ptx);
}

/* Several uploads of one new name at once without REPLACE: exactly one wins. */
static void concurrent_uploads_of_one_name_one_wins(void **state)
{
    (void)state;
    size_t len;
    void *ptx = st_fixture_default_ptx(&len, 4);
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
    stc_conn *c = st_daemon_client(&D1, NULL);
    assert_int_equal(stc_delete(c, "raced"), 0);
    stc_close(c);
    free(ptx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(upload_info_fetch_delete_round_trip),
        cmocka_unit_test(upload_with_wrong_crc_is_corrupt),
        cmocka_unit_test(upload_with_a_corrupt_stored_reduction_is_refused),
        cmocka_unit_test(dropped_upload_resumes_on_a_new_connection),
        cmocka_unit_test(kept_uploads_expire_and_can_be_turned_off),
        cmocka_unit_test(a_killed_daemons_uploads_without_a_data_dir_go_at_the_next_start),
        cmocka_unit_test(concurrent_uploads_of_one_name_one_wins),
    };
    static const char *const args[] = {"--heavy-batch", "2048", NULL};
    st_group_args = args;
    return cmocka_run_group_tests_name("server_upload", tests, st_group_setup,
                                       st_group_teardown);
}
