/* server/h_upload.h - the upload and delete handlers and the import of one file (h_upload.c).
 *
 * Owns: the UPLOAD_*, REPLICA_PUBLISH and DELETE entries of the dispatch table
 * (sts_handler_fn, dispatch.h: one reply frame appended to the caller's `out`),
 * sts_import_path, publishing and dropping staged copies. Does not own: the
 * upload records (uploads.h), the start-up load (startup.h).
 */
#ifndef STS_H_UPLOAD_H
#define STS_H_UPLOAD_H

#include "dispatch.h"
#include "registry.h"

STS_HANDLER(sts_h_upload_begin);
STS_HANDLER(sts_h_upload_chunk);
STS_HANDLER(sts_h_upload_commit);
STS_HANDLER(sts_h_upload_abort);
STS_HANDLER(sts_h_upload_status);
STS_HANDLER(sts_h_delete);
/* REPLICA_PUBLISH (cluster nodes): publishes this node's staged copy of a set by name and
 * CRC-32, once its writer has recorded the write (PROTOCOL.md 4.11). */
STS_HANDLER(sts_h_replica_publish);

/* Imports one file into a new set, with the upload's options ("texture=<set>", "cube=...",
 * "colorspace=..."); the reader is chosen by the content's magic (fmt is the extension the
 * file was given from it). On success *out is a set the caller owns (st_set_free, or hand
 * it to the registry); ST_EBUSY when a texture= set is not loaded. Used by UPLOAD_COMMIT
 * (recorded 0) and by the start-up load (startup.c) and staged copies (recorded 1: options a
 * manifest recorded are taken as they were accepted then, st_import_opts.cube_lenient). */
int sts_import_path(sts_server *srv, const char *path, const char *fmt, const char *options,
                    int recorded, st_set **out, st_error *e);

/* Removes set `name` from this node: durably from the data dir (when it is there), then from
 * the registry. 0, ST_ENOTFOUND, or another store code. DELETE and the cluster's repair. */
int sts_delete_local(sts_server *srv, const char *name);

/* A cluster write's staged copy (store/service/datadir.h "Staged copies"): published under its
 * set's name, replacing this node's copy in the data dir and the registry (under commit_mu),
 * from set when given (ownership passes) or imported from the staged source; ST_ENOTFOUND
 * when another thread published or dropped it meanwhile. The write path once the write is
 * recorded, and the repair pass for a copy the catalogue records "ok". */
int sts_publish_staged(sts_server *srv, const char *id, st_set *set, int *replaced, st_error *e);

/* Drops staged copy id (logged with why; quiet when it is gone already). */
void sts_drop_staged(sts_server *srv, const char *id, const char *why);

#endif
