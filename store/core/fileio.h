/* store/core/fileio.h - whole-file reads under a cap and whole-file writes that a crash cannot
 * leave half done, in the store's error convention, for every reader and writer of the store
 * (ptex, dds, obj, draco). The data dir (service/datadir.c) has its own commit protocol on top
 * of the same steps (util/fdio.h).
 *
 * Ownership: st_file_read returns a buffer to free with free() (plus one zero byte after the data) that
 * the caller frees.
 */
#ifndef ST_FILEIO_H
#define ST_FILEIO_H

#include <stddef.h>

#include "err.h"

/* Reads the whole file at path into *out (*len bytes). ST_ENOTFOUND when it does not exist,
 * ST_ETOOBIG over cap bytes (checked before allocating), ST_ENOMEM, ST_EIO otherwise; the
 * message names the path. */
int st_file_read(const char *path, size_t cap, void **out, size_t *len, st_error *e);

/* Writes len bytes to "<path>.tmp", fsyncs it, renames it over path and fsyncs the folder, so
 * a reader or a restart after a crash sees the old file or the new one, never a part. The
 * temp file is removed on failure. Returns 0 or ST_EINVAL (path too long) / ST_EIO. */
int st_file_write_atomic(const char *path, const void *buf, size_t len, st_error *e);

#endif
