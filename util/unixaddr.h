/* util/unixaddr.h - the "unix:/path" address form shared by the daemon (--listen), the client
 * library, the CLI, the load tester and the Python module, libc only.
 *
 * Owns: recognising the form and turning it into a sockaddr_un. Does not own: binding,
 * permissions, stale sockets (server/listen_unix.c) or connecting (each caller).
 * Convention as util/fdio.h: 0, or -1 with errno set.
 */
#ifndef STU_UNIXADDR_H
#define STU_UNIXADDR_H

#include <sys/socket.h>
#include <sys/un.h>

#define STU_UNIX_PREFIX "unix:"

/* 1 when s is a "unix:..." address (whatever follows), 0 otherwise (NULL too). */
int stu_is_unix_addr(const char *s);

/* Fills *sa and *len from "unix:PATH". PATH must be non-empty, hold no 0 byte (it cannot)
 * and fit sun_path with its terminator (107 bytes on Linux): else -1, errno EINVAL (not the
 * form, empty path) or ENAMETOOLONG. */
int stu_unix_addr(const char *s, struct sockaddr_un *sa, socklen_t *len);

#endif
