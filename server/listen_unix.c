/* server/listen_unix.c - the listening Unix domain socket (listen_unix.h).
 *
 * The file gets its mode without a window: the socket is bound under a temporary name in the
 * same folder, chmod'ed, put to listen, then renamed over the final path (rename is atomic),
 * so no client ever sees the final path with the umask's mode.
 */
#include "listen_unix.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "log.h"
#include "unixaddr.h"

/* 1 when a server accepts connections on the socket at sa, 0 when nobody does (stale),
 * -1 when it cannot be told (errno). */
static int someone_listens(const struct sockaddr_un *sa, socklen_t len)
{
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    int r = connect(fd, (const struct sockaddr *)sa, len);
    int e = errno;
    close(fd);
    if (r == 0 || e == EAGAIN)   /* EAGAIN: its backlog is full, so it is alive */
        return 1;
    if (e == ECONNREFUSED)
        return 0;
    errno = e;
    return -1;
}

int sts_unix_listen(sts_unix_listener *u, const char *addr, unsigned mode, sts_log *log)
{
    struct sockaddr_un sa, tmp;
    socklen_t len, tlen;
    memset(u, 0, sizeof *u);
    if (stu_unix_addr(addr, &sa, &len) != 0) {
        sts_logf(log, STS_ERROR, "listen %s: %s", addr, errno == ENAMETOOLONG
                 ? "the path is too long for a Unix socket (107 bytes at most)"
                 : "not unix:PATH");
        return -1;
    }
    char tname[sizeof tmp.sun_path + 32];
    snprintf(tname, sizeof tname, "unix:%s.%ld.tmp", sa.sun_path, (long)getpid());
    if (stu_unix_addr(tname, &tmp, &tlen) != 0) {
        sts_logf(log, STS_ERROR, "listen %s: the path is too long for a Unix socket (its "
                 "temporary name needs %zu more bytes)", addr, strlen(tname) - strlen(addr));
        return -1;
    }
    struct stat st;
    if (lstat(sa.sun_path, &st) == 0) {
        if (!S_ISSOCK(st.st_mode)) {
            sts_logf(log, STS_ERROR, "listen %s: the path exists and is not a socket", addr);
            return -1;
        }
        int l = someone_listens(&sa, len);
        if (l != 0) {
            sts_logf(log, STS_ERROR, "listen %s: %s", addr, l > 0
                     ? "another server is listening on this socket"
                     : strerror(errno));
            return -1;
        }
        if (unlink(sa.sun_path) != 0 && errno != ENOENT) {
            sts_logf(log, STS_ERROR, "listen %s: removing the stale socket: %s", addr,
                     strerror(errno));
            return -1;
        }
        sts_logf(log, STS_INFO, "listen %s: removed a stale socket nobody listened on", addr);
    }
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) {
        sts_logf(log, STS_ERROR, "listen %s: socket: %s", addr, strerror(errno));
        return -1;
    }
    unlink(tmp.sun_path);   /* ours from an earlier run with the same pid, if any */
    const char *step = "bind";
    if (bind(fd, (struct sockaddr *)&tmp, tlen) != 0)
        goto fail;
    step = "chmod";
    if (chmod(tmp.sun_path, mode & 0777) != 0)
        goto fail_tmp;
    step = "listen";
    if (listen(fd, 4096) != 0)
        goto fail_tmp;
    step = "stat";
    if (lstat(tmp.sun_path, &st) != 0)
        goto fail_tmp;
    step = "rename";
    if (rename(tmp.sun_path, sa.sun_path) != 0)
        goto fail_tmp;
    snprintf(u->path, sizeof u->path, "%s", sa.sun_path);
    u->dev = st.st_dev;
    u->ino = st.st_ino;
    return fd;
fail_tmp:;
    int e = errno;
    unlink(tmp.sun_path);
    errno = e;
fail:
    sts_logf(log, STS_ERROR, "listen %s: %s: %s", addr, step, strerror(errno));
    close(fd);
    return -1;
}

void sts_unix_unlink(sts_unix_listener *u)
{
    struct stat st;
    if (u->path[0] && lstat(u->path, &st) == 0 && st.st_dev == u->dev && st.st_ino == u->ino)
        unlink(u->path);
    u->path[0] = 0;
}
