/* server/startup.h - loading the data dir at start (startup.c).
 *
 * Owns: sts_load_datadir. Does not own: the data dir's on-disk rules (store/datadir.h), the
 * import of one file (h_upload.h: sts_import_path).
 */
#ifndef STS_STARTUP_H
#define STS_STARTUP_H

typedef struct sts_server sts_server;

/* Loads every set of srv->dd (none: returns 0) into the registry; sets that do not load are
 * set aside by the data dir and logged. Returns the sets loaded, or < 0 (logged) when the
 * data dir cannot be read. Runs before any thread starts; the sets belong to the registry. */
int sts_load_datadir(sts_server *srv);

#endif
