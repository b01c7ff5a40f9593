/* util/shmfd.c - a sealed memfd for shared-memory sampling, and passing a descriptor with
 * bytes on a Unix socket (shmfd.h).
 */
#include "shmfd.h"

#include <errno.h>
#include <stdint.h>
#include <fcntl.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <unistd.h>

int stu_memfd_sealed(const char *name, size_t bytes, int *fd, void **map)
{
    *fd = -1;
    *map = NULL;
    if (bytes == 0 || (unsigned long long)bytes > (unsigned long long)INT64_MAX) {
        errno = EINVAL;
        return -1;
    }
    int f = memfd_create(name ? name : "seamtex-shm", MFD_CLOEXEC | MFD_ALLOW_SEALING);
    if (f < 0)
        return -1;
    if (ftruncate(f, (off_t)bytes) != 0 ||
        fcntl(f, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL) != 0)
        goto fail;
    void *p = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, f, 0);
    if (p == MAP_FAILED)
        goto fail;
    *fd = f;
    *map = p;
    return 0;
fail:;
    int e = errno;
    close(f);
    errno = e;
    return -1;
}

ssize_t stu_send_with_fd(int sock, const void *buf, size_t len, int fd)
{
    union {
        struct cmsghdr h;
        char b[CMSG_SPACE(sizeof(int))];
    } ctl;
    struct iovec iov = { (void *)buf, len };
    struct msghdr m;
    memset(&m, 0, sizeof m);
    memset(&ctl, 0, sizeof ctl);
    m.msg_iov = &iov;
    m.msg_iovlen = 1;
    m.msg_control = ctl.b;
    m.msg_controllen = sizeof ctl.b;
    struct cmsghdr *h = CMSG_FIRSTHDR(&m);
    h->cmsg_level = SOL_SOCKET;
    h->cmsg_type = SCM_RIGHTS;
    h->cmsg_len = CMSG_LEN(sizeof(int));
    memcpy(CMSG_DATA(h), &fd, sizeof fd);
    ssize_t n;
    do {
        n = sendmsg(sock, &m, MSG_NOSIGNAL);
    } while (n < 0 && errno == EINTR);
    return n;
}
