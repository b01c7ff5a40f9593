/* store/fileio.c - atomic whole-file writes (see fileio.h). */
#include "fileio.h"

#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

static int fsync_dir_of(const char *path)
{
    char copy[4096];
    snprintf(copy, sizeof copy, "%s", path);
    int fd = open(dirname(copy), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    int rc = fsync(fd);
    close(fd);
    return rc;
}

int st_file_write_atomic(const char *path, const void *buf, size_t len, st_error *e)
{
    char tmp[4096];
    if ((size_t)snprintf(tmp, sizeof tmp, "%s.tmp", path) >= sizeof tmp)
        return st_fail(e, ST_EINVAL, "path too long: %s", path);
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        return st_fail(e, ST_EIO, "%s: %s", tmp, strerror(errno));
    int rc = ST_OK;
    const uint8_t *p = buf;
    size_t left = len;
    while (left) {
        ssize_t k = write(fd, p, left);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0) {
            rc = st_fail(e, ST_EIO, "%s: write failed: %s", tmp, strerror(errno));
            break;
        }
        p += k;
        left -= (size_t)k;
    }
    if (!rc && fsync(fd) != 0)
        rc = st_fail(e, ST_EIO, "%s: fsync failed: %s", tmp, strerror(errno));
    if (close(fd) != 0 && !rc)
        rc = st_fail(e, ST_EIO, "%s: close failed: %s", tmp, strerror(errno));
    if (!rc && rename(tmp, path) != 0)
        rc = st_fail(e, ST_EIO, "rename %s -> %s: %s", tmp, path, strerror(errno));
    if (rc) {
        unlink(tmp);
        return rc;
    }
    if (fsync_dir_of(path) != 0)
        return st_fail(e, ST_EIO, "fsync of the folder of %s failed: %s", path, strerror(errno));
    return ST_OK;
}
