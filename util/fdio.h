/* util/fdio.h - blocking file-descriptor helpers shared by every part of seamtex (store,
 * server, client), libc only.
 *
 * Owns: writing a whole buffer, reading a whole buffer, reading a whole file under a cap,
 * fsyncing a folder, removing a tree. Does not own: any error convention above errno (callers turn -1/errno
 * into their layer's codes: ST_E* in store/, statuses in server/, STC_E* in client/).
 *
 * Convention: 0 on success, -1 with errno set on failure. EINTR is retried. A short write or
 * read that makes no progress (write returning 0, read hitting end of file early) fails with
 * errno EIO.
 *
 * Ownership: stu_read_file returns a buffer the caller frees with free() (with one extra zero
 * byte after the data, so text parsers may rely on a terminator). Files of 256 KiB and more
 * are read into huge pages (bigalloc.h, STU_BIG_TEMP: meant to be parsed and freed soon).
 */
#ifndef STU_FDIO_H
#define STU_FDIO_H

#include <stddef.h>

/* Writes all n bytes of p to fd. */
int stu_write_all(int fd, const void *p, size_t n);

/* Reads exactly n bytes from fd into p (EIO at an early end of file). */
int stu_read_all(int fd, void *p, size_t n);

/* Reads the whole regular file at path into *out (*len bytes, plus a zero byte). A file over
 * cap bytes fails with EFBIG before anything is allocated; ENOMEM when the buffer cannot be
 * had. */
int stu_read_file(const char *path, size_t cap, void **out, size_t *len);

/* fsyncs the folder `dir` (so that a rename or create in it is durable). */
int stu_fsync_dir(const char *dir);

/* fsyncs the folder that holds `path`. */
int stu_fsync_parent(const char *path);

/* Removes path and, for a folder, everything under it (symbolic links themselves, never
 * what they point to). Best effort: goes on past what it cannot remove; 0, or -1 when path
 * is still there afterwards. */
int stu_remove_tree(const char *path);

#endif
