/* tests/common/faultinject.c - the --wrap shim behind faultinject.h.
 *
 * Every __wrap_X asks fi_hit(kind) and either fails or calls __real_X. Linked only into the
 * binaries that are built with the matching -Wl,--wrap flags (nothing else references these
 * symbols, so the archive member is never pulled into other tests).
 */
#include "faultinject.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

static int armed_kind = -1;
static unsigned long armed_n;
static fi_how armed_how;
static int armed_persist;
static unsigned long calls;
static int fired;

void fi_arm(fi_kind kind, unsigned long n, fi_how how, int persist)
{
    __atomic_store_n(&calls, 0, __ATOMIC_SEQ_CST);
    fired = 0;
    armed_n = n;
    armed_how = how;
    armed_persist = persist;
    __atomic_store_n(&armed_kind, (int)kind, __ATOMIC_SEQ_CST);
}

void fi_disarm(void) { __atomic_store_n(&armed_kind, -1, __ATOMIC_SEQ_CST); }
unsigned long fi_count(void) { return __atomic_load_n(&calls, __ATOMIC_SEQ_CST); }
int fi_fired(void) { return fired; }

const char *fi_kind_name(fi_kind k)
{
    static const char *const n[] = {"alloc", "open", "write", "fsync", "rename"};
    return k < FI_NKINDS ? n[k] : "?";
}

const char *fi_how_name(fi_how h)
{
    static const char *const n[] = {"EIO", "ENOSPC", "short", "ENOMEM"};
    return h <= FI_ENOMEM ? n[h] : "?";
}

/* 0: go on; otherwise the errno to fail with, or -1: a short write. */
static int fi_hit(fi_kind kind)
{
    if (__atomic_load_n(&armed_kind, __ATOMIC_SEQ_CST) != (int)kind)
        return 0;
    unsigned long c = __atomic_add_fetch(&calls, 1, __ATOMIC_SEQ_CST);
    if (!armed_n || c < armed_n || (c > armed_n && !armed_persist))
        return 0;
    fired = 1;
    if (kind == FI_ALLOC)
        return ENOMEM;
    if (armed_how == FI_SHORT)
        return kind == FI_WRITE ? -1 : EIO;
    return armed_how == FI_ENOSPC ? ENOSPC : EIO;
}

void *__real_malloc(size_t n);
void *__real_calloc(size_t a, size_t b);
void *__real_realloc(void *p, size_t n);
char *__real_strdup(const char *s);
void *__real_aligned_alloc(size_t al, size_t n);
int __real_posix_memalign(void **p, size_t al, size_t n);
int __real_open(const char *p, int flags, ...);
int __real_openat(int dirfd, const char *p, int flags, ...);
FILE *__real_fopen(const char *p, const char *mode);
ssize_t __real_write(int fd, const void *b, size_t n);
ssize_t __real_pwrite(int fd, const void *b, size_t n, off_t off);
int __real_fsync(int fd);
int __real_fdatasync(int fd);
int __real_rename(const char *a, const char *b);
int __real_renameat(int da, const char *a, int db, const char *b);
int __real_link(const char *a, const char *b);
int __real_mkdir(const char *p, mode_t mode);

void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t a, size_t b);
void *__wrap_realloc(void *p, size_t n);
char *__wrap_strdup(const char *s);
void *__wrap_aligned_alloc(size_t al, size_t n);
int __wrap_posix_memalign(void **p, size_t al, size_t n);
int __wrap_open(const char *p, int flags, ...);
int __wrap_openat(int dirfd, const char *p, int flags, ...);
FILE *__wrap_fopen(const char *p, const char *mode);
ssize_t __wrap_write(int fd, const void *b, size_t n);
ssize_t __wrap_pwrite(int fd, const void *b, size_t n, off_t off);
int __wrap_fsync(int fd);
int __wrap_fdatasync(int fd);
int __wrap_rename(const char *a, const char *b);
int __wrap_renameat(int da, const char *a, int db, const char *b);
int __wrap_link(const char *a, const char *b);
int __wrap_mkdir(const char *p, mode_t mode);

#define FAIL_IF(kind, ret)                  \
    do {                                    \
        int e_ = fi_hit(kind);              \
        if (e_ > 0) {                       \
            errno = e_;                     \
            return ret;                     \
        }                                   \
    } while (0)

void *__wrap_malloc(size_t n) { FAIL_IF(FI_ALLOC, NULL); return __real_malloc(n); }
void *__wrap_calloc(size_t a, size_t b) { FAIL_IF(FI_ALLOC, NULL); return __real_calloc(a, b); }
void *__wrap_realloc(void *p, size_t n) { FAIL_IF(FI_ALLOC, NULL); return __real_realloc(p, n); }
char *__wrap_strdup(const char *s) { FAIL_IF(FI_ALLOC, NULL); return __real_strdup(s); }
void *__wrap_aligned_alloc(size_t al, size_t n)
{
    FAIL_IF(FI_ALLOC, NULL);
    return __real_aligned_alloc(al, n);
}
int __wrap_posix_memalign(void **p, size_t al, size_t n)
{
    int e_ = fi_hit(FI_ALLOC);
    if (e_ > 0)
        return e_;      /* posix_memalign reports through its result, not errno */
    return __real_posix_memalign(p, al, n);
}

static mode_t open_mode(int flags, va_list ap)
{
    return (flags & (O_CREAT | __O_TMPFILE)) ? (mode_t)va_arg(ap, int) : 0;
}

int __wrap_open(const char *p, int flags, ...)
{
    va_list ap;
    va_start(ap, flags);
    mode_t mode = open_mode(flags, ap);
    va_end(ap);
    FAIL_IF(FI_OPEN, -1);
    return __real_open(p, flags, mode);
}

int __wrap_openat(int dirfd, const char *p, int flags, ...)
{
    va_list ap;
    va_start(ap, flags);
    mode_t mode = open_mode(flags, ap);
    va_end(ap);
    FAIL_IF(FI_OPEN, -1);
    return __real_openat(dirfd, p, flags, mode);
}

FILE *__wrap_fopen(const char *p, const char *mode) { FAIL_IF(FI_OPEN, NULL); return __real_fopen(p, mode); }

ssize_t __wrap_write(int fd, const void *b, size_t n)
{
    int e = fi_hit(FI_WRITE);
    if (e > 0) {
        errno = e;
        return -1;
    }
    if (e < 0 && n > 1)
        n /= 2;
    return __real_write(fd, b, n);
}

ssize_t __wrap_pwrite(int fd, const void *b, size_t n, off_t off)
{
    int e = fi_hit(FI_WRITE);
    if (e > 0) {
        errno = e;
        return -1;
    }
    if (e < 0 && n > 1)
        n /= 2;
    return __real_pwrite(fd, b, n, off);
}

int __wrap_fsync(int fd) { FAIL_IF(FI_FSYNC, -1); return __real_fsync(fd); }
int __wrap_fdatasync(int fd) { FAIL_IF(FI_FSYNC, -1); return __real_fdatasync(fd); }
int __wrap_rename(const char *a, const char *b) { FAIL_IF(FI_RENAME, -1); return __real_rename(a, b); }
int __wrap_renameat(int da, const char *a, int db, const char *b)
{
    FAIL_IF(FI_RENAME, -1);
    return __real_renameat(da, a, db, b);
}
int __wrap_link(const char *a, const char *b) { FAIL_IF(FI_RENAME, -1); return __real_link(a, b); }
int __wrap_mkdir(const char *p, mode_t mode) { FAIL_IF(FI_RENAME, -1); return __real_mkdir(p, mode); }
