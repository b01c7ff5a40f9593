/* server/listen_unix.h - the listening Unix domain socket of `--listen unix:/path`
 * (listen_unix.c).
 *
 * Owns: creating the socket file with its mode (--unix-mode) without a window in which it
 * has another mode, refusing to take over a path another server listens on, removing a stale
 * socket left by a server that died, and removing the file at exit when it is still ours.
 * Does not own: accepting (io.c: the same loop serves TCP and Unix connections), the address
 * form (util/unixaddr.h).
 * Access control is the file's permissions: a client needs write permission on the socket
 * (and search permission on its folders) or connect() fails with EACCES in the kernel.
 */
#ifndef STS_LISTEN_UNIX_H
#define STS_LISTEN_UNIX_H

#include <sys/types.h>

typedef struct sts_log sts_log;

typedef struct sts_unix_listener {
    char  path[108];   /* "" when not listening on a Unix socket */
    dev_t dev;         /* the socket file we made (not removed at exit if replaced) */
    ino_t ino;
} sts_unix_listener;

/* Listens on "unix:PATH" with file mode `mode` (0..0777). A path that exists and is not a
 * socket, or a socket a server accepts on, is an error; a socket nobody listens on (a
 * crashed server's) is removed first, with a log line. Returns the listening fd
 * (non-blocking, close-on-exec) or -1 (logged). */
int sts_unix_listen(sts_unix_listener *u, const char *addr, unsigned mode, sts_log *log);

/* Removes the socket file if it is still the one sts_unix_listen made. */
void sts_unix_unlink(sts_unix_listener *u);

#endif
