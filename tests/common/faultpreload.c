/* tests/common/faultpreload.c - an LD_PRELOAD object that makes seamtexd's file calls fail on
 * demand, for the end-to-end fault tests (tests/integration/test_faults_daemon.c).
 *
 * Owns: interposing open/openat/creat, write/pwrite, fsync/fdatasync, rename/renameat/link/
 * mkdir (dlsym(RTLD_NEXT) for the real ones), counting the calls of one kind on paths under one
 * folder while armed, and failing the Nth with EIO, ENOSPC or a short write (half the bytes).
 * Does not own: allocation faults (the in-process shim tests/common/faultinject.c does those;
 * interposing malloc under ASan is not worth it), what a failure means (the tests check that).
 *
 * Built as $(B)/tests/libfaultpreload.so (tests/module.mk), never linked into a binary (it is
 * left out of libtestutil.a: it defines write, open, ...). Control, read on every interposed
 * call so that one daemon can be armed and disarmed while it runs:
 *   SEAMTEX_FAULT_PATH  only calls on this path or below it count (the data dir); socket
 *                       writes and the log never match
 *   SEAMTEX_FAULT_CTL   a folder: the test writes "<session> <kind> <n> <how>" into <ctl>/arm
 *                       (kind open|write|fsync|rename, n >= 1 fails the nth call, 0 counts only,
 *                       how EIO|ENOSPC|short) and removes it to disarm; the preload rewrites
 *                       <ctl>/state as "<session> <calls counted> <fired 0|1>" after each
 *                       counted call. A new session number restarts the count.
 * Kind "rename" covers rename, renameat, link and mkdir (the namespace steps of a commit).
 * Its own file I/O uses raw syscalls, so it never recurses into itself.
 */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/types.h>
#include <unistd.h>

enum { K_OPEN, K_WRITE, K_FSYNC, K_RENAME, K_N };
static const char *const KNAME[K_N] = {"open", "write", "fsync", "rename"};

static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static long cur_session = -1;
static unsigned long counted;
static int fired;

#define REAL(ret, name, args)                                                   \
    static ret(*real_##name) args;                                              \
    static void load_##name(void)                                               \
    {                                                                           \
        if (!real_##name)                                                       \
            *(void **)&real_##name = dlsym(RTLD_NEXT, #name);                   \
    }
REAL(int, open, (const char *, int, ...))
REAL(int, open64, (const char *, int, ...))
REAL(int, openat, (int, const char *, int, ...))
REAL(int, openat64, (int, const char *, int, ...))
REAL(int, creat, (const char *, mode_t))
REAL(ssize_t, write, (int, const void *, size_t))
REAL(ssize_t, pwrite, (int, const void *, size_t, off_t))
REAL(ssize_t, pwrite64, (int, const void *, size_t, off_t))
REAL(int, fsync, (int))
REAL(int, fdatasync, (int))
REAL(int, rename, (const char *, const char *))
REAL(int, renameat, (int, const char *, int, const char *))
REAL(int, link, (const char *, const char *))
REAL(int, mkdir, (const char *, mode_t))

static ssize_t raw_read_file(const char *path, char *buf, size_t cap)
{
    int fd = (int)syscall(SYS_openat, AT_FDCWD, path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    ssize_t n = syscall(SYS_read, fd, buf, cap - 1);
    syscall(SYS_close, fd);
    if (n < 0)
        return -1;
    buf[n] = 0;
    return n;
}

static void raw_write_file(const char *path, const char *text)
{
    char tmp[4300];
    snprintf(tmp, sizeof tmp, "%.4200s.new", path);
    int fd = (int)syscall(SYS_openat, AT_FDCWD, tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC,
                          0644);
    if (fd < 0)
        return;
    syscall(SYS_write, fd, text, strlen(text));
    syscall(SYS_close, fd);
    syscall(SYS_renameat, AT_FDCWD, tmp, AT_FDCWD, path);
}

/* 1 when path (absolute, or relative to dirfd) lies under SEAMTEX_FAULT_PATH. */
static int path_matches(int dirfd, const char *path)
{
    const char *pre = getenv("SEAMTEX_FAULT_PATH");
    if (!pre || !*pre || !path)
        return 0;
    char full[8192];
    if (path[0] == '/') {
        snprintf(full, sizeof full, "%s", path);
    } else {
        char link[64], dir[4096];
        ssize_t n;
        if (dirfd == AT_FDCWD) {
            n = syscall(SYS_getcwd, dir, sizeof dir) > 0 ? (ssize_t)strlen(dir) : -1;
        } else {
            snprintf(link, sizeof link, "/proc/self/fd/%d", dirfd);
            n = syscall(SYS_readlinkat, AT_FDCWD, link, dir, sizeof dir - 1);
            if (n >= 0)
                dir[n] = 0;
        }
        if (n < 0)
            return 0;
        snprintf(full, sizeof full, "%s/%s", dir, path);
    }
    size_t pl = strlen(pre);
    return !strncmp(full, pre, pl) && (full[pl] == 0 || full[pl] == '/');
}

static int fd_matches(int fd)
{
    char link[64], target[4096];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t n = syscall(SYS_readlinkat, AT_FDCWD, link, target, sizeof target - 1);
    if (n <= 0 || target[0] != '/')
        return 0;
    target[n] = 0;
    return path_matches(AT_FDCWD, target);
}

/* Decides one call of `kind` on a matching path: 0 go on, else the errno to fail with, or -1
 * for a short write. */
static int decide(int kind)
{
    const char *ctl = getenv("SEAMTEX_FAULT_CTL");
    if (!ctl || !*ctl)
        return 0;
    char path[4200], text[256];
    snprintf(path, sizeof path, "%s/arm", ctl);
    if (raw_read_file(path, text, sizeof text) <= 0)
        return 0;
    long session = -1;
    unsigned long n = 0;
    char k[16] = "", how[16] = "";
    if (sscanf(text, "%ld %15s %lu %15s", &session, k, &n, how) != 4 || strcmp(k, KNAME[kind]))
        return 0;
    int out = 0;
    pthread_mutex_lock(&mu);
    if (session != cur_session) {
        cur_session = session;
        counted = 0;
        fired = 0;
    }
    counted++;
    if (n && counted == n) {
        fired = 1;
        out = !strcmp(how, "ENOSPC") ? ENOSPC : !strcmp(how, "short") && kind == K_WRITE ? -1 : EIO;
    }
    snprintf(text, sizeof text, "%ld %lu %d\n", session, counted, fired);
    snprintf(path, sizeof path, "%s/state", ctl);
    raw_write_file(path, text);
    pthread_mutex_unlock(&mu);
    return out;
}

static int fail_path(int kind, int dirfd, const char *p)
{
    int e = 0;
    if (path_matches(dirfd, p))
        e = decide(kind);
    return e > 0 ? e : 0;
}

#define OPEN_MODE(flags, mode)                                                  \
    mode_t mode = 0;                                                            \
    if ((flags) & (O_CREAT | __O_TMPFILE)) {                                    \
        va_list ap;                                                             \
        va_start(ap, flags);                                                    \
        mode = (mode_t)va_arg(ap, int);                                         \
        va_end(ap);                                                             \
    }

int open(const char *p, int flags, ...)
{
    OPEN_MODE(flags, mode);
    load_open();
    int e = fail_path(K_OPEN, AT_FDCWD, p);
    if (e) { errno = e; return -1; }
    return real_open(p, flags, mode);
}

int open64(const char *p, int flags, ...)
{
    OPEN_MODE(flags, mode);
    load_open64();
    int e = fail_path(K_OPEN, AT_FDCWD, p);
    if (e) { errno = e; return -1; }
    return real_open64(p, flags, mode);
}

int openat(int dirfd, const char *p, int flags, ...)
{
    OPEN_MODE(flags, mode);
    load_openat();
    int e = fail_path(K_OPEN, dirfd, p);
    if (e) { errno = e; return -1; }
    return real_openat(dirfd, p, flags, mode);
}

int openat64(int dirfd, const char *p, int flags, ...)
{
    OPEN_MODE(flags, mode);
    load_openat64();
    int e = fail_path(K_OPEN, dirfd, p);
    if (e) { errno = e; return -1; }
    return real_openat64(dirfd, p, flags, mode);
}

int creat(const char *p, mode_t mode)
{
    load_creat();
    int e = fail_path(K_OPEN, AT_FDCWD, p);
    if (e) { errno = e; return -1; }
    return real_creat(p, mode);
}

static int write_decide(int fd, size_t *n)
{
    if (!fd_matches(fd))
        return 0;
    int e = decide(K_WRITE);
    if (e < 0) {
        if (*n > 1)
            *n /= 2;
        return 0;
    }
    return e;
}

ssize_t write(int fd, const void *b, size_t n)
{
    load_write();
    int e = write_decide(fd, &n);
    if (e) { errno = e; return -1; }
    return real_write(fd, b, n);
}

ssize_t pwrite(int fd, const void *b, size_t n, off_t off)
{
    load_pwrite();
    int e = write_decide(fd, &n);
    if (e) { errno = e; return -1; }
    return real_pwrite(fd, b, n, off);
}

ssize_t pwrite64(int fd, const void *b, size_t n, off_t off)
{
    load_pwrite64();
    int e = write_decide(fd, &n);
    if (e) { errno = e; return -1; }
    return real_pwrite64(fd, b, n, off);
}

int fsync(int fd)
{
    load_fsync();
    int e = fd_matches(fd) ? decide(K_FSYNC) : 0;
    if (e > 0) { errno = e; return -1; }
    return real_fsync(fd);
}

int fdatasync(int fd)
{
    load_fdatasync();
    int e = fd_matches(fd) ? decide(K_FSYNC) : 0;
    if (e > 0) { errno = e; return -1; }
    return real_fdatasync(fd);
}

int rename(const char *a, const char *b)
{
    load_rename();
    int e = path_matches(AT_FDCWD, a) || path_matches(AT_FDCWD, b) ? decide(K_RENAME) : 0;
    if (e > 0) { errno = e; return -1; }
    return real_rename(a, b);
}

int renameat(int da, const char *a, int db, const char *b)
{
    load_renameat();
    int e = path_matches(da, a) || path_matches(db, b) ? decide(K_RENAME) : 0;
    if (e > 0) { errno = e; return -1; }
    return real_renameat(da, a, db, b);
}

int link(const char *a, const char *b)
{
    load_link();
    int e = path_matches(AT_FDCWD, b) ? decide(K_RENAME) : 0;
    if (e > 0) { errno = e; return -1; }
    return real_link(a, b);
}

int mkdir(const char *p, mode_t mode)
{
    load_mkdir();
    int e = fail_path(K_RENAME, AT_FDCWD, p);
    if (e) { errno = e; return -1; }
    return real_mkdir(p, mode);
}
