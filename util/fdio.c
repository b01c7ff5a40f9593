/* util/fdio.c - blocking file-descriptor helpers (see fdio.h). */
#include "fdio.h"
#include "loadpath.h"

#include "bigalloc.h"

#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int stu_write_all(int fd, const void *buf, size_t n)
{
    const uint8_t *p = buf;
    while (n) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0)
            return -1;
        if (w == 0) {
            errno = EIO;
            return -1;
        }
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

STU_LOADPATH
int stu_read_all(int fd, void *buf, size_t n)
{
    uint8_t *p = buf;
    while (n) {
        ssize_t r = read(fd, p, n);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return -1;
        if (r == 0) {
            errno = EIO;
            return -1;
        }
        p += r;
        n -= (size_t)r;
    }
    return 0;
}

STU_LOADPATH
int stu_read_file(const char *path, size_t cap, void **out, size_t *len)
{
    *out = NULL;
    *len = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    /* fstat(fd) as fstatat(fd, "", AT_EMPTY_PATH) with the "" on the stack: glibc's fstat
     * passes a "" of its own read-only data, which the kernel reads, and in a fresh process
     * that first read is a page fault of 10-30 us on the project's VM (a whole small
     * import is 100-200 us) */
    struct stat st;
    char empty[1] = {0};
    if (fstatat(fd, empty, &st, AT_EMPTY_PATH) != 0)
        goto fail;
    if (!S_ISREG(st.st_mode)) {
        errno = S_ISDIR(st.st_mode) ? EISDIR : EINVAL;
        goto fail;
    }
    if (st.st_size < 0 || (uint64_t)st.st_size > (uint64_t)cap ||
        (uint64_t)st.st_size >= (uint64_t)SIZE_MAX) {
        errno = EFBIG;
        goto fail;
    }
    size_t n = (size_t)st.st_size;
    uint8_t *b = stu_big_alloc(n + 1, STU_BIG_TEMP);
    if (!b) {
        errno = ENOMEM;
        goto fail;
    }
    if (stu_read_all(fd, b, n) != 0) {
        int err = errno;
        free(b);
        errno = err;
        goto fail;
    }
    b[n] = 0;
    close(fd);
    *out = b;
    *len = n;
    return 0;
fail: {
    int err = errno;
    close(fd);
    errno = err;
    return -1;
}
}

int stu_fsync_dir(const char *dir)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    int rc = fsync(fd);
    int err = errno;
    close(fd);
    errno = err;
    return rc;
}

int stu_fsync_parent(const char *path)
{
    char dir[4096];
    size_t n = strlen(path);
    if (n >= sizeof dir) {
        errno = ENAMETOOLONG;
        return -1;
    }
    memcpy(dir, path, n + 1);
    char *slash = strrchr(dir, '/');
    if (!slash)
        return stu_fsync_dir(".");
    if (slash == dir)
        slash[1] = 0;
    else
        *slash = 0;
    return stu_fsync_dir(dir);
}

static int remove_cb(const char *p, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb;
    (void)ftw;
    if (flag == FTW_DP)
        rmdir(p);
    else
        unlink(p);
    return 0;  /* keep going: best effort */
}

int stu_remove_tree(const char *path)
{
    nftw(path, remove_cb, 16, FTW_DEPTH | FTW_PHYS);
    struct stat st;
    return lstat(path, &st) == 0 ? -1 : 0;
}
