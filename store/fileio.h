/* store/fileio.h - whole-file writes that a crash cannot leave half done, for the writers of
 * the store (ptex_write.c, dds.c). The data dir (datadir.c) has its own commit protocol on top
 * of the same steps. */
#ifndef ST_FILEIO_H
#define ST_FILEIO_H

#include <stddef.h>

#include "err.h"

/* Writes len bytes to "<path>.tmp", fsyncs it, renames it over path and fsyncs the folder, so
 * a reader or a restart after a crash sees the old file or the new one, never a part. The
 * temp file is removed on failure. Returns 0 or ST_EINVAL (path too long) / ST_EIO. */
int st_file_write_atomic(const char *path, const void *buf, size_t len, st_error *e);

#endif
