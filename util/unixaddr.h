/* util/unixaddr.h - the "unix:/path" address form shared by the daemon (--listen), the client
 * library, the CLI, the load tester and the Python module, libc only.
 *
 * Owns: recognising the form and turning it into a sockaddr_un, and the send buffer every
 * Unix stream socket of ours asks for (stu_unix_sndbuf). Does not own: binding,
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

/* The send buffer asked for on every Unix stream socket (daemon and clients): a Unix stream
 * socket's in-flight bytes are bounded by the SENDER's SO_SNDBUF alone (the default,
 * net.core.wmem_default, is 208 KiB), so a 16384-query SAMPLE request (458 KiB) or its reply
 * (256 KiB) otherwise crosses in pieces, each a write, a wake-up of the peer and a wait for
 * EPOLLOUT. 4 MiB is conn-out-cap's default; the kernel caps it at net.core.wmem_max. It is
 * a limit, not an allocation: an idle socket holds nothing more. */
#define STU_UNIX_SNDBUF (4 << 20)

/* Asks for STU_UNIX_SNDBUF on fd (a Unix stream socket). Best effort: the kernel's cap or a
 * refusal leaves the socket as it was and is not an error. */
void stu_unix_sndbuf(int fd);

#endif
