/* util/unixaddr.c - "unix:/path" addresses (unixaddr.h). */
#include "unixaddr.h"

#include <errno.h>
#include <stddef.h>
#include <string.h>

int stu_is_unix_addr(const char *s)
{
    return s && strncmp(s, STU_UNIX_PREFIX, sizeof STU_UNIX_PREFIX - 1) == 0;
}

int stu_unix_addr(const char *s, struct sockaddr_un *sa, socklen_t *len)
{
    if (!stu_is_unix_addr(s) || !s[sizeof STU_UNIX_PREFIX - 1]) {
        errno = EINVAL;
        return -1;
    }
    const char *path = s + sizeof STU_UNIX_PREFIX - 1;
    size_t n = strlen(path);
    memset(sa, 0, sizeof *sa);
    if (n >= sizeof sa->sun_path) {
        errno = ENAMETOOLONG;
        return -1;
    }
    sa->sun_family = AF_UNIX;
    memcpy(sa->sun_path, path, n + 1);
    *len = (socklen_t)(offsetof(struct sockaddr_un, sun_path) + n + 1);
    return 0;
}

void stu_unix_sndbuf(int fd)
{
    int n = STU_UNIX_SNDBUF;
    (void)setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &n, sizeof n);
}
