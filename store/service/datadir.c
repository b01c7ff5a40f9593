/* store/service/datadir.c - the durable data directory (layout and commit protocol in datadir.h).
 *
 * Owns: every file operation under the data dir. Does not own: parsing source files (the
 * caller's load/publish callbacks import them), the registry.
 * Load: one commit costs two fsyncs of data (part file, manifest) and two of directories;
 * commits serialise on d->mu.
 */
#include "datadir.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include "registry.h"
#include "fdio.h"
#include "native.h"

#define PATHCAP 4096

struct st_datadir {
    pthread_mutex_t mu;
    char            root[PATHCAP - 512];   /* leaves room for sets/<255-byte name>/<file> */
    uint64_t        counter;  /* atomic; makes ids unique inside this process */
    st_datadir_warn_fn warn;  /* a commit went on without its native file (may be NULL) */
    void           *warn_arg;
};

const char *st_datadir_path(const st_datadir *d) { return d->root; }

void st_datadir_set_warn(st_datadir *d, st_datadir_warn_fn warn, void *arg)
{
    d->warn = warn;
    d->warn_arg = arg;
}

/* ---- small helpers ------------------------------------------------------------------------ */

/* snprintf into a PATHCAP buffer. The root is at most PATHCAP - 512 bytes, a set name at most
 * 255 and the files inside a set directory under 100, so paths fit; vsnprintf truncates
 * safely if they ever do not. */
static void pathf(char *out, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void pathf(char *out, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(out, PATHCAP, fmt, ap);
    va_end(ap);
}

/* fsyncs a file (dir 0) or a folder (dir 1) through util/fdio.h's rules. */
static int fsync_path(const char *path, int dir, st_error *e)
{
    int rc;
    if (dir) {
        rc = stu_fsync_dir(path);
    } else {
        int fd = open(path, O_RDONLY | O_CLOEXEC);
        if (fd < 0)
            return st_fail(e, ST_EIO, "open %s for fsync: %s", path, strerror(errno));
        rc = fsync(fd);
        int err = errno;
        close(fd);
        errno = err;
    }
    if (rc != 0)
        return st_fail(e, ST_EIO, "fsync %s: %s", path, strerror(errno));
    return 0;
}

static int mkdir_p1(const char *path, st_error *e)
{
    if (mkdir(path, 0700) == 0 || errno == EEXIST) {
        struct stat st;
        if (stat(path, &st) == 0 && S_ISDIR(st.st_mode))
            return 0;
        return st_fail(e, ST_EIO, "%s exists and is not a directory", path);
    }
    return st_fail(e, ST_EIO, "mkdir %s: %s", path, strerror(errno));
}

/* Empties a directory (keeps the directory itself). */
static void empty_dir(const char *dir)
{
    DIR *dp = opendir(dir);
    if (!dp)
        return;
    struct dirent *de;
    char p[PATHCAP];
    while ((de = readdir(dp))) {
        if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
            continue;
        pathf(p, "%s/%s", dir, de->d_name);
        (void)stu_remove_tree(p);
    }
    closedir(dp);
}

static void new_id(st_datadir *d, char *out, size_t cap)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    uint64_t c = __atomic_add_fetch(&d->counter, 1, __ATOMIC_RELAXED);
    snprintf(out, cap, "%" PRIx64 "-%x-%" PRIx64,
             (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec, (unsigned)getpid(), c);
}

/* The manifest of a new source file source-<id>.<fmt> (commit and stage alike). */
static void manifest_fill(st_manifest *m, const char *name, const char *fmt, uint64_t bytes,
                          uint32_t crc, const char *options, const char *id)
{
    memset(m, 0, sizeof *m);
    snprintf(m->name, sizeof m->name, "%s", name);
    snprintf(m->format, sizeof m->format, "%s", fmt);
    m->bytes = bytes;
    m->crc = crc;
    snprintf(m->options, sizeof m->options, "%s", options ? options : "");
    snprintf(m->source, sizeof m->source, "source-%s.%s", id, fmt);
}

/* "<dir>/<name>.<id>" for trash/ and broken/, the name cut so that the last component fits
 * NAME_MAX (255 bytes): a 255-byte set name plus its id would not. */
static void aside_path(char *out, const char *dir, const char *name, const char *id)
{
    size_t keep = 255 - 1 - strlen(id);
    pathf(out, "%s/%.*s.%s", dir, (int)keep, name, id);
}

int st_format_check(const char *fmt, st_error *e)
{
    size_t n = fmt ? strlen(fmt) : 0;
    if (n == 0 || n > 8)
        return st_fail(e, ST_EINVAL, "source format must be 1..8 characters");
    for (size_t i = 0; i < n; i++) {
        char c = fmt[i];
        if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9')))
            return st_fail(e, ST_EINVAL, "source format '%.8s': only a-z and 0-9", fmt);
    }
    return 0;
}

int st_file_crc(const char *path, uint64_t *bytes, uint32_t *crc, st_error *e)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return st_fail(e, ST_EIO, "open %s: %s", path, strerror(errno));
    static const size_t BUF = 1 << 16;
    unsigned char *buf = malloc(BUF);
    if (!buf) {
        close(fd);
        return st_fail(e, ST_ENOMEM, "crc buffer");
    }
    uLong c = crc32(0L, Z_NULL, 0);
    uint64_t total = 0;
    for (;;) {
        ssize_t r = read(fd, buf, BUF);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0) {
            int err = errno;
            free(buf);
            close(fd);
            return st_fail(e, ST_EIO, "read %s: %s", path, strerror(err));
        }
        if (r == 0)
            break;
        c = crc32(c, buf, (uInt)r);
        total += (uint64_t)r;
    }
    free(buf);
    close(fd);
    *bytes = total;
    *crc = (uint32_t)c;
    return 0;
}

/* ---- manifest ------------------------------------------------------------------------------ */

int st_manifest_read(const char *path, st_manifest *m, st_error *e)
{
    memset(m, 0, sizeof *m);
    FILE *f = fopen(path, "re");
    if (!f)
        return st_fail(e, errno == ENOENT ? ST_ENOTFOUND : ST_EIO, "open %s: %s", path,
                       strerror(errno));
    char line[1200];
    int step = 0, rc = 0;
    while (!rc && fgets(line, sizeof line, f)) {
        size_t n = strlen(line);
        if (n == 0 || line[n - 1] != '\n') {
            rc = st_fail(e, ST_EFORMAT, "%s: line %d is truncated or too long", path, step + 1);
            break;
        }
        line[n - 1] = 0;
        char *v = strchr(line, ' ');
        if (v)
            *v++ = 0;
        static const char *const keys[] = {"seamtex-set", "name", "source", "format",
                                           "bytes", "crc32", "options", "end"};
        if (step >= 8 || strcmp(line, keys[step]) != 0 || (step < 6 && !v) || (step == 7 && v)) {
            rc = st_fail(e, ST_EFORMAT, "%s: line %d: expected '%s'", path, step + 1,
                         step < 8 ? keys[step] : "(nothing)");
            break;
        }
        char *end = NULL;
        switch (step) {
        case 0:
            if (strcmp(v, "1") != 0)
                rc = st_fail(e, ST_EUNSUPPORTED, "%s: manifest version %s", path, v);
            break;
        case 1:
            rc = st_name_check(v, strlen(v), e);
            if (!rc)
                snprintf(m->name, sizeof m->name, "%s", v);
            break;
        case 2:
            if (strlen(v) >= sizeof m->source || strchr(v, '/') || v[0] == '.' || !v[0])
                rc = st_fail(e, ST_EFORMAT, "%s: bad source file name", path);
            else
                snprintf(m->source, sizeof m->source, "%s", v);
            break;
        case 3:
            rc = st_format_check(v, e);
            if (!rc)
                snprintf(m->format, sizeof m->format, "%s", v);
            break;
        case 4:
            errno = 0;
            m->bytes = strtoull(v, &end, 10);
            if (errno || !end || *end || v[0] == '-')
                rc = st_fail(e, ST_EFORMAT, "%s: bad bytes '%s'", path, v);
            break;
        case 5: {
            unsigned long x = strtoul(v, &end, 16);
            if (!end || *end || strlen(v) != 8)
                rc = st_fail(e, ST_EFORMAT, "%s: bad crc32 '%s'", path, v);
            m->crc = (uint32_t)x;
            break;
        }
        case 6:
            if (v && strlen(v) >= sizeof m->options)
                rc = st_fail(e, ST_EFORMAT, "%s: options too long", path);
            else
                snprintf(m->options, sizeof m->options, "%s", v ? v : "");
            break;
        default:
            break;
        }
        step++;
    }
    fclose(f);
    if (!rc && step != 8)
        rc = st_fail(e, ST_EFORMAT, "%s: manifest ends after %d lines", path, step);
    return rc;
}

/* Writes the manifest to tmp_path and fsyncs it. */
static int manifest_write(const char *tmp_path, const st_manifest *m, st_error *e)
{
    char text[1600];
    int n = snprintf(text, sizeof text,
                     "seamtex-set 1\nname %s\nsource %s\nformat %s\nbytes %" PRIu64
                     "\ncrc32 %08x\noptions%s%s\nend\n",
                     m->name, m->source, m->format, m->bytes, (unsigned)m->crc,
                     m->options[0] ? " " : "", m->options);
    int fd = open(tmp_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0)
        return st_fail(e, ST_EIO, "create %s: %s", tmp_path, strerror(errno));
    if (stu_write_all(fd, text, (size_t)n) != 0 || fsync(fd) != 0) {
        int err = errno;
        close(fd);
        unlink(tmp_path);
        return st_fail(e, ST_EIO, "write %s: %s", tmp_path, strerror(err));
    }
    close(fd);
    return 0;
}

/* ---- open / close -------------------------------------------------------------------------- */

int st_datadir_open(const char *path, st_datadir **out, st_error *e)
{
    *out = NULL;
    if (!path || !*path)
        return st_fail(e, ST_EINVAL, "no data dir given");
    st_datadir *d = calloc(1, sizeof *d);
    if (!d)
        return st_fail(e, ST_ENOMEM, "datadir");
    if (strlen(path) >= sizeof d->root) {
        free(d);
        return st_fail(e, ST_EINVAL, "data dir path is too long");
    }
    snprintf(d->root, sizeof d->root, "%s", path);
    size_t n = strlen(d->root);
    while (n > 1 && d->root[n - 1] == '/')
        d->root[--n] = 0;
    pthread_mutex_init(&d->mu, NULL);
    char p[PATHCAP];
    int rc = mkdir_p1(d->root, e);
    static const char *const subs[] = {"sets", "tmp", "trash", "broken", "staged"};
    for (int i = 0; !rc && i < 5; i++) {
        pathf(p, "%s/%s", d->root, subs[i]);
        rc = mkdir_p1(p, e);
    }
    if (rc) {
        st_datadir_close(d);
        return rc;
    }
    pathf(p, "%s/tmp", d->root);
    empty_dir(p);
    pathf(p, "%s/trash", d->root);
    empty_dir(p);
    fsync_path(d->root, 1, NULL);
    *out = d;
    return 0;
}

void st_datadir_close(st_datadir *d)
{
    if (!d)
        return;
    pthread_mutex_destroy(&d->mu);
    free(d);
}

int st_datadir_tmpfile(st_datadir *d, char *path, size_t cap, int *fd, st_error *e)
{
    char id[64];
    new_id(d, id, sizeof id);
    int n = snprintf(path, cap, "%s/tmp/%s.part", d->root, id);
    if (n < 0 || (size_t)n >= cap)
        return st_fail(e, ST_EINVAL, "temp path buffer too small");
    *fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (*fd < 0)
        return st_fail(e, ST_EIO, "create %s: %s", path, strerror(errno));
    return 0;
}

void st_datadir_discard(const char *tmp_path)
{
    if (tmp_path && *tmp_path)
        unlink(tmp_path);
}

/* ---- commit / delete ------------------------------------------------------------------------ */

int st_datadir_commit(st_datadir *d, const char *name, const char *tmp_path, const char *fmt,
                      const char *options, uint64_t bytes, st_publish_fn publish, void *arg,
                      st_error *e)
{
    return st_datadir_commit_set(d, name, tmp_path, fmt, options, bytes, NULL, publish, arg, e);
}

/* Writes set as tmp/<id>.native for source m (fsynced), its path in path. Returns 0, or a
 * code and why (may be NULL) says why: the file is then removed, path still names it (the
 * caller empties it; the set is committed without one and gets it at the next start). */
static int native_tmp(st_datadir *d, const st_set *set, const st_manifest *m, char *path,
                      st_error *why)
{
    char id[64];
    new_id(d, id, sizeof id);
    pathf(path, "%s/tmp/%s.native", d->root, id);
    st_native_source src;
    memset(&src, 0, sizeof src);
    src.bytes = m->bytes;
    src.crc = m->crc;
    snprintf(src.name, sizeof src.name, "%s", m->source);
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    st_error we;
    st_error_clear(&we);
    int rc = fd < 0 ? st_fail(&we, ST_EIO, "create: %s", strerror(errno))
                    : st_native_write_fd(fd, set, &src, &we);
    if (!rc && fsync(fd) != 0)
        rc = st_fail(&we, ST_EIO, "fsync: %s", strerror(errno));
    if (rc && !we.msg[0])
        st_fail(&we, rc, "%s", st_strerror(rc));
    if (fd >= 0)
        close(fd);
    if (rc && why)
        *why = we;
    if (rc)
        unlink(path);
    return rc;
}

/* Rolls sets/<name>/set.native back to what it was before a commit touched it: the old file
 * (hard-linked to prevnat) when there was one, else none. */
static void restore_native(int touched, int had_nat, const char *prevnat, const char *nat)
{
    if (!touched)
        return;
    if (!had_nat || rename(prevnat, nat) != 0)
        unlink(nat); /* no old file, or it cannot be put back: rebuilt from the source at start */
    unlink(prevnat);
}

/* The checks of a commit's arguments (name, format, options). */
static int commit_args(const char *name, const char *fmt, const char *options, st_error *e)
{
    int rc = st_name_check(name, name ? strlen(name) : 0, e);
    if (!rc)
        rc = st_format_check(fmt, e);
    if (!rc && options) {
        if (strlen(options) >= sizeof ((st_manifest *)0)->options)
            rc = st_fail(e, ST_EINVAL, "import options are too long");
        for (const char *p = options; !rc && *p; p++)
            if ((unsigned char)*p < 0x20 || (unsigned char)*p > 0x7e)
                rc = st_fail(e, ST_EINVAL, "import options must be printable ASCII");
    }
    return rc;
}

static int commit_set(st_datadir *d, const char *name, const char *tmp_path, const char *fmt,
                      const char *options, uint64_t bytes, const uint32_t *want_crc,
                      st_set **set, st_publish_fn publish, void *arg, st_error *e);

int st_datadir_commit_set(st_datadir *d, const char *name, const char *tmp_path, const char *fmt,
                          const char *options, uint64_t bytes, st_set **set,
                          st_publish_fn publish, void *arg, st_error *e)
{
    return commit_set(d, name, tmp_path, fmt, options, bytes, NULL, set, publish, arg, e);
}

/* The checks a new source file passes before it becomes a set's (committed or staged): the
 * arguments, its size against the announced bytes, its CRC-32 (into *crc; against *want_crc
 * when given: a staged copy's manifest's), and an fsync. */
static int check_source(const char *name, const char *tmp_path, const char *fmt,
                        const char *options, uint64_t bytes, const uint32_t *want_crc,
                        uint32_t *crc, st_error *e)
{
    int rc = commit_args(name, fmt, options, e);
    uint64_t got_bytes = 0;
    if (!rc)
        rc = st_file_crc(tmp_path, &got_bytes, crc, e);
    if (!rc && got_bytes != bytes)
        rc = st_fail(e, ST_ECORRUPT, "upload has %" PRIu64 " bytes, %" PRIu64 " were announced",
                     got_bytes, bytes);
    if (!rc && want_crc && *crc != *want_crc)
        rc = st_fail(e, ST_ECORRUPT, "file has crc32 %08x, %08x was recorded", *crc, *want_crc);
    if (!rc)
        rc = fsync_path(tmp_path, 0, e);
    return rc;
}

/* want_crc (may be NULL): the CRC-32 the file must have (a staged copy's manifest's) */
static int commit_set(st_datadir *d, const char *name, const char *tmp_path, const char *fmt,
                      const char *options, uint64_t bytes, const uint32_t *want_crc,
                      st_set **set, st_publish_fn publish, void *arg, st_error *e)
{
    uint32_t got_crc = 0;
    int rc = check_source(name, tmp_path, fmt, options, bytes, want_crc, &got_crc, e);
    if (rc) {
        st_datadir_discard(tmp_path);
        return rc;
    }

    char id[64];
    new_id(d, id, sizeof id);
    st_manifest m;
    manifest_fill(&m, name, fmt, bytes, got_crc, options, id);

    char setdir[PATHCAP], src[PATHCAP], man[PATHCAP], mantmp[PATHCAP], sets[PATHCAP];
    char ntmp[PATHCAP], nat[PATHCAP];
    pathf(sets, "%s/sets", d->root);
    pathf(setdir, "%s/%s", sets, name);
    pathf(src, "%s/%s", setdir, m.source);
    pathf(man, "%s/manifest", setdir);
    pathf(mantmp, "%s/tmp/%s.manifest", d->root, id);
    pathf(nat, "%s/" ST_DATADIR_NATIVE, setdir);
    /* the native file is written (and fsynced) before the lock: it is the long part */
    ntmp[0] = 0;
    if (set && *set) {
        st_error nwe;
        st_error_clear(&nwe);
        if (native_tmp(d, *set, &m, ntmp, &nwe) != 0) {
            if (d->warn)
                d->warn(d->warn_arg, name, ntmp, nwe.msg);
            ntmp[0] = 0;
        }
    }

    char prev[PATHCAP];   /* a hard link to the old manifest, to roll back to */
    pathf(prev, "%s/tmp/%s.prev", d->root, id);
    char prevnat[PATHCAP]; /* a hard link to the old native file, likewise */
    pathf(prevnat, "%s/tmp/%s.prevnative", d->root, id);
    int nat_touched = 0, had_nat = 0;

    pthread_mutex_lock(&d->mu);
    st_manifest old;
    st_error oe;
    int orc = st_manifest_read(man, &old, &oe);
    int had_old = orc == 0;                 /* a valid manifest: its source goes at the end */
    int had_file = orc != ST_ENOTFOUND;     /* a manifest file, to put back on a rollback */
    if (orc && orc != ST_ENOTFOUND && orc != ST_EFORMAT && orc != ST_EUNSUPPORTED) {
        /* cannot tell whether a set is there (EIO, ENOMEM): touch nothing */
        st_datadir_discard(tmp_path);
        if (ntmp[0])
            unlink(ntmp);
        pthread_mutex_unlock(&d->mu);
        return st_fail(e, orc, "%s", oe.msg);
    }
    int newdir = 0;
    if (mkdir(setdir, 0700) == 0)
        newdir = 1;
    else if (errno != EEXIST)
        rc = st_fail(e, ST_EIO, "mkdir %s: %s", setdir, strerror(errno));
    if (!rc && rename(tmp_path, src) != 0)
        rc = st_fail(e, ST_EIO, "rename %s -> %s: %s", tmp_path, src, strerror(errno));
    /* the old set's native file, hard-linked to tmp/<id>.prevnative so that a rollback can put
     * it back (a crash leaves the link in tmp/, emptied at open) */
    if (!rc) {
        nat_touched = 1;
        had_nat = link(nat, prevnat) == 0;
    }
    /* before the commit point: a crash here leaves the old manifest beside a native file that
     * names the new source, which the next start refuses and rebuilds from the old source */
    if (!rc && ntmp[0] && rename(ntmp, nat) != 0) {
        char why[128];
        snprintf(why, sizeof why, "rename: %s", strerror(errno));
        if (d->warn)
            d->warn(d->warn_arg, name, nat, why);
        unlink(ntmp);
        ntmp[0] = 0;
    }
    if (!rc && !ntmp[0])
        unlink(nat);  /* never leave an older set's native file beside the new manifest */
    if (!rc)
        rc = manifest_write(mantmp, &m, e);
    if (!rc && had_file && link(man, prev) != 0)
        rc = st_fail(e, ST_EIO, "link %s -> %s: %s", man, prev, strerror(errno));
    if (!rc && rename(mantmp, man) != 0)   /* the commit point */
        rc = st_fail(e, ST_EIO, "rename %s -> %s: %s", mantmp, man, strerror(errno));
    if (rc) {
        unlink(src);
        unlink(mantmp);
        unlink(prev);
        if (ntmp[0])
            unlink(ntmp);  /* not renamed yet (or already gone) */
        restore_native(nat_touched, had_nat, prevnat, nat);
        st_datadir_discard(tmp_path);
        if (newdir) {
            unlink(nat);
            rmdir(setdir);
        }
        pthread_mutex_unlock(&d->mu);
        return rc;
    }
    rc = fsync_path(setdir, 1, e);
    if (!rc)
        rc = fsync_path(sets, 1, e);
    /* serve the set from its native file from now on: the heap copy goes (on a rollback
     * below the caller frees the mapped set; the mapping outlives the file's name) */
    if (!rc && ntmp[0] && set && *set) {
        st_set *mapped = NULL;
        if (st_native_open(nat, 0, NULL, &mapped, NULL) == 0) {
            st_set_free(*set);
            *set = mapped;
        }
    }
    if (!rc && publish)
        rc = publish(arg, &m, src);
    if (rc) {
        /* Failed after the commit point (an fsync, or publish): the caller answers an error,
         * so the set must not appear at the next start either. Put the old manifest back (or
         * remove the new set), so disk, registry and reply agree. A crash before this lands
         * leaves the new set, which is then an upload in flight, not a lost one. */
        if ((had_file ? rename(prev, man) : unlink(man)) != 0 && e)
            snprintf(e->msg + strlen(e->msg), sizeof e->msg - strlen(e->msg),
                     " (and rolling back failed: %s)", strerror(errno));
        unlink(src);
        unlink(prev);
        restore_native(nat_touched, had_nat, prevnat, nat); /* the old one back, or none */
        if (newdir)
            rmdir(setdir);
        stu_fsync_dir(setdir);
        stu_fsync_dir(sets);
        pthread_mutex_unlock(&d->mu);
        return rc;
    }
    unlink(prev);
    unlink(prevnat);
    if (had_old && strcmp(old.source, m.source) != 0) {
        char oldsrc[PATHCAP];
        pathf(oldsrc, "%s/%s", setdir, old.source);
        unlink(oldsrc);
    }
    pthread_mutex_unlock(&d->mu);
    return rc;
}

int st_datadir_delete(st_datadir *d, const char *name,
                      int (*unpublish)(void *arg, const char *name), void *arg, st_error *e)
{
    int rc = st_name_check(name, name ? strlen(name) : 0, e);
    if (rc)
        return rc;
    char setdir[PATHCAP], dst[PATHCAP], sets[PATHCAP], trash[PATHCAP], id[64];
    new_id(d, id, sizeof id);
    pathf(sets, "%s/sets", d->root);
    pathf(trash, "%s/trash", d->root);
    pathf(setdir, "%s/%s", sets, name);
    aside_path(dst, trash, name, id);
    pthread_mutex_lock(&d->mu);
    /* as a commit: a manifest that cannot be read (a set left unloaded at start because of
     * its permissions, or a failing disk) says nothing about what is there: touch nothing */
    char man[PATHCAP];
    pathf(man, "%s/manifest", setdir);
    st_manifest old;
    st_error oe;
    int orc = st_manifest_read(man, &old, &oe);
    if (orc && orc != ST_ENOTFOUND && orc != ST_EFORMAT && orc != ST_EUNSUPPORTED) {
        pthread_mutex_unlock(&d->mu);
        return st_fail(e, orc, "%s", oe.msg);
    }
    if (rename(setdir, dst) != 0) {
        int err = errno;
        pthread_mutex_unlock(&d->mu);
        if (err == ENOENT)
            return st_fail(e, ST_ENOTFOUND, "no set named '%s' on disk", name);
        return st_fail(e, ST_EIO, "rename %s -> %s: %s", setdir, dst, strerror(err));
    }
    rc = fsync_path(sets, 1, e);
    if (!rc && unpublish)
        rc = unpublish(arg, name);
    pthread_mutex_unlock(&d->mu);
    (void)stu_remove_tree(dst);
    return rc;
}

/* ---- load ----------------------------------------------------------------------------------- */

static int cmp_str(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

static void move_broken(st_datadir *d, const char *name, const char *setdir)
{
    char dst[PATHCAP], broken[PATHCAP], id[64];
    new_id(d, id, sizeof id);
    pathf(broken, "%s/broken", d->root);
    aside_path(dst, broken, name, id);
    rename(setdir, dst);  /* when it cannot be moved it stays, unloaded, for the next start */
}

/* An error that says nothing about the set itself (memory, a failing disk call): the set is
 * left where it is and the load stops, rather than setting an acknowledged set aside. */
static int transient(int rc) { return rc == ST_ENOMEM || rc == ST_EIO; }

/* The names in sets/, sorted (*names malloc'ed, each name too; the caller frees them). A
 * set missing from the list would be a set missing after the start: out of memory fails. */
static int list_sets(const char *sets, char ***out, size_t *count, st_error *e)
{
    *out = NULL;
    *count = 0;
    DIR *dp = opendir(sets);
    if (!dp)
        return st_fail(e, ST_EIO, "open %s: %s", sets, strerror(errno));
    char **names = NULL;
    size_t n = 0, cap = 0;
    struct dirent *de;
    while ((de = readdir(dp))) {
        if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
            continue;
        if (n == cap) {
            cap = cap ? cap * 2 : 32;
            char **nn = realloc(names, cap * sizeof *nn);
            if (!nn)
                goto oom;
            names = nn;
        }
        names[n] = strdup(de->d_name);
        if (!names[n])
            goto oom;
        n++;
    }
    closedir(dp);
    if (n)
        qsort(names, n, sizeof *names, cmp_str);
    *out = names;
    *count = n;
    return 0;
oom:
    /* a set missing from the list would be a set missing after the start: fail instead */
    closedir(dp);
    for (size_t k = 0; k < n; k++)
        free(names[k]);
    free(names);
    return st_fail(e, ST_ENOMEM, "listing %s: out of memory", sets);
}

/* ---- load with native files ------------------------------------------------------------------ */

static int64_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static void say(const st_datadir_loader *L, const char *name, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void say(const st_datadir_loader *L, const char *name, const char *fmt, ...)
{
    if (!L->note)
        return;
    char msg[ST_ERRMSG_LEN + 200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    L->note(L->arg, name, msg);
}

/* Moves a refused native file to broken/<name>.<id>.native (never silently dropped). */
static void native_aside(st_datadir *d, const char *name, const char *nat)
{
    char dst[PATHCAP], broken[PATHCAP], id[64];
    new_id(d, id, sizeof id);
    pathf(broken, "%s/broken", d->root);
    size_t keep = 255 - 8 - strlen(id);
    pathf(dst, "%s/%.*s.%s.native", broken, (int)keep, name, id);
    if (rename(nat, dst) != 0)
        unlink(nat);
}

/* One set dir: 1 published, 0 removed or moved to broken/, ST_EBUSY "later", another negative
 * code (in e) when an error that says nothing about the set stops the load (transient():
 * the set is left in place). Caller holds d->mu. *built counts native files written. */
static int load_one_native(st_datadir *d, const char *sets, const char *name,
                           const st_datadir_loader *L, int final, int *built, st_error *e)
{
    struct dirent *de;
    char setdir[PATHCAP], man[PATHCAP], src[PATHCAP], nat[PATHCAP];
    pathf(setdir, "%s/%s", sets, name);
    pathf(man, "%s/manifest", setdir);
    pathf(nat, "%s/" ST_DATADIR_NATIVE, setdir);
    st_error err;
    st_error_clear(&err);
    if (st_name_check(name, strlen(name), &err) != 0) {
        if (L->report)
            L->report(L->arg, name, err.msg);
        move_broken(d, "badname", setdir);
        return 0;
    }
    /* An entry that is not a directory (a file an operator left in sets/) is no set: it goes
     * to broken/ (never removed) instead of failing the start with ENOTDIR. */
    struct stat dst;
    if (stat(setdir, &dst) == 0 && !S_ISDIR(dst.st_mode)) {
        if (L->report)
            L->report(L->arg, name, "not a set directory: moved to broken/");
        move_broken(d, name, setdir);
        return 0;
    }
    /* A set this process may not read (its directory or manifest has the wrong owner or
     * mode) says nothing about the set and nothing about the others: it stays where it is,
     * unloaded and reported, and the start goes on (a commit of that name refuses with EIO,
     * as it cannot read the manifest either). Fixing its permissions loads it next start. */
    const char *denied = NULL;
    if (faccessat(AT_FDCWD, setdir, R_OK | X_OK, AT_EACCESS) != 0 &&
        (errno == EACCES || errno == EPERM))
        denied = "its directory";
    else if (faccessat(AT_FDCWD, man, R_OK, AT_EACCESS) != 0 &&
             (errno == EACCES || errno == EPERM))
        denied = "its manifest";
    if (denied) {
        if (L->report) {
            char w[160];
            snprintf(w, sizeof w, "%s cannot be read (%s): left in place, not loaded; fix its "
                     "permissions and restart", denied, strerror(EACCES));
            L->report(L->arg, name, w);
        }
        return 0;
    }
    st_manifest m;
    int rc = st_manifest_read(man, &m, &err);
    if (rc == ST_ENOTFOUND) {
        if (L->report)
            L->report(L->arg, name, "no manifest (interrupted upload): removed");
        (void)stu_remove_tree(setdir);
        return 0;
    }
    if (!rc && strcmp(m.name, name) != 0)
        rc = st_fail(&err, ST_EFORMAT, "manifest names '%s'", m.name);
    struct stat sst;
    if (!rc) {
        /* files the manifest does not name (an interrupted replace) go; the native file stays */
        DIR *sd = opendir(setdir);
        while (sd && (de = readdir(sd))) {
            if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, "..") ||
                !strcmp(de->d_name, "manifest") || !strcmp(de->d_name, m.source) ||
                !strcmp(de->d_name, ST_DATADIR_NATIVE))
                continue;
            pathf(src, "%s/%s", setdir, de->d_name);
            (void)stu_remove_tree(src);
        }
        if (sd)
            closedir(sd);
        pathf(src, "%s/%s", setdir, m.source);
        if (stat(src, &sst) != 0)
            /* gone (deleted by hand): the set is bad, not the disk; a failing call stays EIO */
            rc = st_fail(&err, errno == ENOENT || errno == ENOTDIR ? ST_ECORRUPT : ST_EIO,
                         "source %s: %s", m.source, strerror(errno));
        else if ((uint64_t)sst.st_size != m.bytes)
            rc = st_fail(&err, ST_ECORRUPT, "source has %llu bytes, manifest says %llu",
                         (unsigned long long)sst.st_size, (unsigned long long)m.bytes);
        else if (L->native_flags & ST_NATIVE_VERIFY) {
            /* full verification: the source's bytes too, as before native files */
            uint64_t bytes;
            uint32_t crc;
            rc = st_file_crc(src, &bytes, &crc, &err);
            if (!rc && (bytes != m.bytes || crc != m.crc))
                rc = st_fail(&err, ST_ECORRUPT, "source has %" PRIu64 " bytes crc %08x, manifest "
                             "says %" PRIu64 " bytes crc %08x", bytes, crc, m.bytes, m.crc);
        }
    }
    /* the fast path: the native file, tied to this very source, mapped and checked */
    int native_why = 0;
    char why[ST_ERRMSG_LEN];
    why[0] = 0;
    if (!rc) {
        st_set *set = NULL;
        st_native_source ns;
        st_error ne;
        st_error_clear(&ne);
        int nrc = L->no_native ? ST_ENOTFOUND
                               : st_native_open(nat, L->native_flags, &ns, &set, &ne);
        if (!nrc && (ns.bytes != m.bytes || ns.crc != m.crc || strcmp(ns.name, m.source) != 0)) {
            nrc = ST_EFORMAT;
            snprintf(ne.msg, sizeof ne.msg, "it was built from %s (%llu bytes, crc %08x), the "
                     "manifest names %s", ns.name, (unsigned long long)ns.bytes, ns.crc, m.source);
            st_set_free(set);
            set = NULL;
        }
        if (!nrc) {
            int prc = L->publish(L->arg, &m, set, &err);
            if (prc == 0)
                return 1;
            rc = prc;  /* the registry refused it: as a failed load */
        } else {
            native_why = nrc;
            snprintf(why, sizeof why, "%s", ne.msg);
        }
    }
    if (!rc && native_why) {
        if (native_why != ST_ENOTFOUND && !L->no_native) {
            say(L, name, "native file refused (%s): moved to broken/, rebuilding it from the "
                "source", why);
            native_aside(d, name, nat);
        }
        /* the source is read whole now: it must be the bytes the manifest recorded */
        uint64_t bytes;
        uint32_t crc;
        rc = st_file_crc(src, &bytes, &crc, &err);
        if (!rc && (bytes != m.bytes || crc != m.crc))
            rc = st_fail(&err, ST_ECORRUPT,
                         "source has %" PRIu64 " bytes crc %08x, manifest says %" PRIu64
                         " bytes crc %08x", bytes, crc, m.bytes, m.crc);
        st_set *set = NULL;
        int64_t t0 = now_ms();
        if (!rc) {
            rc = L->import(L->arg, &m, src, &set, &err);
            if (rc == ST_EBUSY && !final)
                return ST_EBUSY;
            if (rc && !err.msg[0])
                snprintf(err.msg, sizeof err.msg, "import failed (%s)", st_strerror(rc));
        }
        if (!rc) {
            char ntmp[PATHCAP];
            ntmp[0] = 0;
            st_error nwe;
            st_error_clear(&nwe);
            if (!L->no_native && native_tmp(d, set, &m, ntmp, &nwe) != 0)
                ntmp[0] = 0;
            st_set *mapped = NULL;
            if (ntmp[0] && rename(ntmp, nat) == 0 && fsync_path(setdir, 1, NULL) == 0 &&
                st_native_open(nat, 0, NULL, &mapped, NULL) == 0) {
                st_set_free(set);
                set = mapped;
                (*built)++;
                say(L, name, "native file %s from the %s source (%lld ms)",
                    native_why == ST_ENOTFOUND ? "built" : "rebuilt", m.format,
                    (long long)(now_ms() - t0));
            } else if (!L->no_native) {
                if (ntmp[0])
                    unlink(ntmp);
                say(L, name, "native file could not be written (%s): served from memory, "
                    "written at a later start", nwe.msg[0] ? nwe.msg : strerror(errno));
            }
            rc = L->publish(L->arg, &m, set, &err);
        }
    }
    if (rc && transient(rc))
        return st_fail(e, rc, "set '%s' left in place, not loaded: %s", name,
                       err.msg[0] ? err.msg : st_strerror(rc));
    if (rc) {
        if (L->report) {
            char w[ST_ERRMSG_LEN + 40];
            snprintf(w, sizeof w, "%s: moved to broken/", err.msg[0] ? err.msg : "load failed");
            L->report(L->arg, name, w);
        }
        move_broken(d, name, setdir);
        return 0;
    }
    return 1;
}

int st_datadir_load_sets(st_datadir *d, const st_datadir_loader *L, st_error *e)
{
    char sets[PATHCAP];
    pathf(sets, "%s/sets", d->root);
    char **names = NULL;
    size_t n = 0;
    int lrc = list_sets(sets, &names, &n, e);
    if (lrc)
        return lrc;

    int loaded = 0, built = 0;
    int64_t t0 = now_ms(), last = t0;
    pthread_mutex_lock(&d->mu);
    size_t left = n, done = 0;
    for (int final = 0; left > 0;) {
        size_t progress = 0, deferred = 0;
        for (size_t i = 0; i < n; i++) {
            if (!names[i])
                continue;
            int r = load_one_native(d, sets, names[i], L, final, &built, e);
            if (r == ST_EBUSY) {
                deferred++;
                continue;
            }
            if (r < 0) {
                pthread_mutex_unlock(&d->mu);
                for (size_t k = 0; k < n; k++)
                    free(names[k]);
                free(names);
                return r;
            }
            if (r == 1) {
                loaded++;
                progress++;
            }
            done++;
            free(names[i]);
            names[i] = NULL;
            int64_t t = now_ms();
            if (L->note && t - last >= 2000) {  /* progress of a long start (an upgrade) */
                last = t;
                char msg[160];
                snprintf(msg, sizeof msg, "%zu of %zu sets done, %d native files built, %lld s",
                         done, n, built, (long long)((t - t0) / 1000));
                L->note(L->arg, "", msg);
            }
        }
        left = deferred;
        if (!progress)
            final = 1;
    }
    pthread_mutex_unlock(&d->mu);
    free(names);
    fsync_path(sets, 1, NULL);
    if (L->built)
        *L->built = built;
    return loaded;
}

/* ---- load through a one-step callback ------------------------------------------------------ */

/* st_datadir_load is st_datadir_load_sets without native files: the caller's callback imports
 * and publishes in one step, so the import hands on no set and publishing is a no-op. */
typedef struct {
    st_publish_fn load;
    void         *arg;
    void        (*report)(void *arg, const char *name, const char *why);
} load_adapter;

static int adapter_import(void *arg, const st_manifest *m, const char *source_path,
                          st_set **out, st_error *e)
{
    (void)e;
    const load_adapter *a = arg;
    *out = NULL;
    return a->load ? a->load(a->arg, m, source_path) : 0;
}

static int adapter_publish(void *arg, const st_manifest *m, st_set *set, st_error *e)
{
    (void)arg; (void)m; (void)set; (void)e;
    return 0;
}

static void adapter_report(void *arg, const char *name, const char *why)
{
    const load_adapter *a = arg;
    a->report(a->arg, name, why);
}

int st_datadir_load(st_datadir *d, st_publish_fn load, void *arg,
                    void (*report)(void *arg, const char *name, const char *why), st_error *e)
{
    load_adapter a = { load, arg, report };
    st_datadir_loader L = {
        .arg = &a, .import = adapter_import, .publish = adapter_publish,
        .report = report ? adapter_report : NULL, .no_native = 1,
    };
    return st_datadir_load_sets(d, &L, e);
}

/* ---- staged copies ---------------------------------------------------------------------------- */

/* A staged id names one directory entry made by new_id: [0-9a-f-], 1..63 bytes. */
static int staged_id_ok(const char *id)
{
    size_t n = id ? strlen(id) : 0;
    if (n == 0 || n >= 64)
        return 0;
    for (size_t i = 0; i < n; i++)
        if (!((id[i] >= '0' && id[i] <= '9') || (id[i] >= 'a' && id[i] <= 'f') || id[i] == '-'))
            return 0;
    return 1;
}

int st_datadir_stage(st_datadir *d, const char *name, const char *tmp_path, const char *fmt,
                     const char *options, uint64_t bytes, char *id_out, size_t cap, st_error *e)
{
    id_out[0] = 0;
    uint32_t got_crc = 0;
    int rc = check_source(name, tmp_path, fmt, options, bytes, NULL, &got_crc, e);
    char id[64];
    new_id(d, id, sizeof id);
    if (!rc && strlen(id) >= cap)
        rc = st_fail(e, ST_EINVAL, "staged id buffer too small");
    if (rc) {
        st_datadir_discard(tmp_path);
        return rc;
    }
    st_manifest m;
    manifest_fill(&m, name, fmt, bytes, got_crc, options, id);
    /* built whole in tmp/ (emptied at open), then one rename into staged/: staged/ only ever
     * holds complete copies */
    char build[PATHCAP], src[PATHCAP], man[PATHCAP], dst[PATHCAP], staged[PATHCAP];
    pathf(build, "%s/tmp/%s.stage", d->root, id);
    pathf(src, "%s/%s", build, m.source);
    pathf(man, "%s/manifest", build);
    pathf(staged, "%s/staged", d->root);
    pathf(dst, "%s/%s", staged, id);
    if (mkdir(build, 0700) != 0)
        rc = st_fail(e, ST_EIO, "mkdir %s: %s", build, strerror(errno));
    if (!rc && rename(tmp_path, src) != 0)
        rc = st_fail(e, ST_EIO, "rename %s -> %s: %s", tmp_path, src, strerror(errno));
    if (!rc)
        rc = manifest_write(man, &m, e);
    if (!rc)
        rc = fsync_path(build, 1, e);
    if (!rc && rename(build, dst) != 0)
        rc = st_fail(e, ST_EIO, "rename %s -> %s: %s", build, dst, strerror(errno));
    if (!rc)
        rc = fsync_path(staged, 1, e);
    if (rc) {
        st_datadir_discard(tmp_path);
        (void)stu_remove_tree(build);
        if (rename(dst, build) == 0)   /* renamed but not durable: not a staged copy */
            (void)stu_remove_tree(build);
        return rc;
    }
    snprintf(id_out, cap, "%s", id);
    return 0;
}

int st_datadir_staged_read(st_datadir *d, const char *id, st_manifest *m, char *source,
                           size_t cap, st_error *e)
{
    if (!staged_id_ok(id))
        return st_fail(e, ST_EINVAL, "bad staged id");
    char man[PATHCAP];
    pathf(man, "%s/staged/%s/manifest", d->root, id);
    int rc = st_manifest_read(man, m, e);
    if (!rc && source) {
        int n = snprintf(source, cap, "%s/staged/%s/%s", d->root, id, m->source);
        if (n < 0 || (size_t)n >= cap)
            rc = st_fail(e, ST_EINVAL, "source path buffer too small");
    }
    return rc;
}

int st_datadir_drop_staged(st_datadir *d, const char *id, st_error *e)
{
    if (!staged_id_ok(id))
        return st_fail(e, ST_EINVAL, "bad staged id");
    char src[PATHCAP], dst[PATHCAP], staged[PATHCAP];
    pathf(staged, "%s/staged", d->root);
    pathf(src, "%s/%s", staged, id);
    pathf(dst, "%s/trash/staged.%s", d->root, id);
    if (rename(src, dst) != 0) {
        int err = errno;
        if (err == ENOENT)
            return st_fail(e, ST_ENOTFOUND, "no staged copy %s", id);
        return st_fail(e, ST_EIO, "rename %s -> %s: %s", src, dst, strerror(err));
    }
    int rc = fsync_path(staged, 1, e);
    (void)stu_remove_tree(dst);
    return rc;
}

int st_datadir_publish_staged(st_datadir *d, const char *id, st_set **set,
                              st_publish_fn publish, void *arg, st_error *e)
{
    st_manifest m;
    char src[PATHCAP], link_path[PATHCAP], lid[64];
    int rc = st_datadir_staged_read(d, id, &m, src, sizeof src, e);
    if (rc)
        return rc;
    /* the commit takes a hard link: the staged copy stays whole until the set is committed
     * (a crash before that leaves it for the next start to publish or drop) */
    new_id(d, lid, sizeof lid);
    pathf(link_path, "%s/tmp/%s.part", d->root, lid);
    if (link(src, link_path) != 0)
        return st_fail(e, errno == ENOENT ? ST_ENOTFOUND : ST_EIO, "link %s -> %s: %s", src,
                       link_path, strerror(errno));
    rc = commit_set(d, m.name, link_path, m.format, m.options, m.bytes, &m.crc, set, publish,
                    arg, e);
    if (rc)
        return rc;
    st_error ignore;
    st_datadir_drop_staged(d, id, &ignore);   /* a leftover is dropped at the next pass */
    return 0;
}

int st_datadir_staged_list(st_datadir *d, st_datadir_staged **out, size_t *count,
                           void (*report)(void *arg, const char *id, const char *why),
                           void *arg, st_error *e)
{
    *out = NULL;
    *count = 0;
    char staged[PATHCAP];
    pathf(staged, "%s/staged", d->root);
    DIR *dp = opendir(staged);
    if (!dp)
        return st_fail(e, ST_EIO, "open %s: %s", staged, strerror(errno));
    st_datadir_staged *v = NULL;
    size_t n = 0, cap = 0;
    struct dirent *de;
    int rc = 0;
    while (!rc && (de = readdir(dp))) {
        if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
            continue;
        char p[PATHCAP];
        pathf(p, "%s/%s", staged, de->d_name);
        st_error me;
        st_error_clear(&me);
        st_manifest m;
        int mrc = staged_id_ok(de->d_name)
                      ? st_datadir_staged_read(d, de->d_name, &m, NULL, 0, &me)
                      : st_fail(&me, ST_EFORMAT, "not a staged id");
        if (mrc == ST_ENOMEM || mrc == ST_EIO) {
            rc = st_fail(e, mrc, "%s", me.msg);
            break;
        }
        struct stat dst;
        if (mrc == ST_ENOTFOUND && lstat(p, &dst) != 0)
            continue;   /* published or dropped by another thread since readdir saw it */
        if (mrc) {   /* never silently dropped */
            if (report)
                report(arg, de->d_name, me.msg);
            char dst[PATHCAP], id[64];
            new_id(d, id, sizeof id);
            pathf(dst, "%s/broken/staged.%.100s.%s", d->root, de->d_name, id);
            rename(p, dst);
            continue;
        }
        struct stat st;
        char man[PATHCAP];
        pathf(man, "%s/manifest", p);
        if (n == cap) {
            cap = cap ? cap * 2 : 8;
            st_datadir_staged *nv = realloc(v, cap * sizeof *nv);
            if (!nv) {
                rc = st_fail(e, ST_ENOMEM, "listing %s: out of memory", staged);
                break;
            }
            v = nv;
        }
        memcpy(v[n].id, de->d_name, strlen(de->d_name) + 1);   /* staged_id_ok: < 64 bytes */
        v[n].m = m;
        v[n].mtime_ms = stat(man, &st) == 0
                            ? (int64_t)st.st_mtim.tv_sec * 1000 + st.st_mtim.tv_nsec / 1000000
                            : 0;
        n++;
    }
    closedir(dp);
    if (rc) {
        free(v);
        return rc;
    }
    *out = v;
    *count = n;
    return 0;
}
