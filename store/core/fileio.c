/* store/core/fileio.c - whole-file reads and atomic whole-file writes (see fileio.h), on top
 * of util/fdio.h. */
#include "fileio.h"
#include "loadpath.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "fdio.h"

STU_LOADPATH
int st_file_read(const char *path, size_t cap, void **out, size_t *len, st_error *e)
{
    if (stu_read_file(path, cap, out, len) == 0)
        return ST_OK;
    switch (errno) {
    case ENOENT: return st_fail(e, ST_ENOTFOUND, "%s: no such file", path);
    case EFBIG:  return st_fail(e, ST_ETOOBIG, "%s: over the %zu byte cap", path, cap);
    case ENOMEM: return st_fail(e, ST_ENOMEM, "%s: out of memory reading the file", path);
    default:     return st_fail(e, ST_EIO, "%s: %s", path, strerror(errno));
    }
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
    if (stu_write_all(fd, buf, len) != 0)
        rc = st_fail(e, ST_EIO, "%s: write failed: %s", tmp, strerror(errno));
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
    if (stu_fsync_parent(path) != 0)
        return st_fail(e, ST_EIO, "fsync of the folder of %s failed: %s", path, strerror(errno));
    return ST_OK;
}
