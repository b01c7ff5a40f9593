/* util/shmfd.h - the client's half of shared-memory sampling (PROTOCOL.md 4.12), libc only:
 * a sealed memfd mapped read-write, and one sendmsg that carries a descriptor with bytes.
 * Shared by the client library (client/libshm.c), the load tester and the tests.
 *
 * Owns: creating and sealing the region, passing a descriptor (SCM_RIGHTS). Does not own:
 * the frames (protocol/), what the region holds (client/libshm.c, the daemon's server/shm.c).
 * Convention as util/fdio.h: 0, or -1 with errno set.
 */
#ifndef STU_SHMFD_H
#define STU_SHMFD_H

#include <stddef.h>
#include <sys/types.h>

/* A memfd of `bytes` (> 0) sealed with F_SEAL_SHRINK, F_SEAL_GROW and F_SEAL_SEAL (the size
 * can never change, so neither side can be made to fault past its end), close-on-exec, mapped
 * shared read-write at *map. The caller closes *fd (once the daemon has it) and munmaps. */
int stu_memfd_sealed(const char *name, size_t bytes, int *fd, void **map);

/* One sendmsg of up to len bytes of buf carrying fd as SCM_RIGHTS ancillary data (the
 * descriptor arrives with the first byte). Returns the bytes sent (the caller writes the rest
 * with plain writes), or -1 with errno. MSG_NOSIGNAL; blocks or not as the socket does. */
ssize_t stu_send_with_fd(int sock, const void *buf, size_t len, int fd);

#endif
