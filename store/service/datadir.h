/* store/service/datadir.h - the daemon's durable data directory.
 *
 * Owns: the on-disk layout, the crash-safe commit of an uploaded source file as a named set,
 * deletion, and the startup scan that finds every committed set and cleans up what a crash
 * left half-written. Does not own: importing or validating a source (import.c / ptex_read.c:
 * the caller imports the file before committing it and again at load), the registry, sockets.
 *
 * Layout (docs/daemon.md, "Data dir"):
 *   <dir>/sets/<name>/manifest              what the set is (text, see below)
 *   <dir>/sets/<name>/source-<id>.<ext>     the uploaded bytes, exactly as received
 *   <dir>/sets/<name>/set.native            the set as the sampler reads it (native.h), built
 *                                           from that source; mapped at start (optional: a
 *                                           set without one is imported and gets one)
 *   <dir>/tmp/                              uploads in progress, manifest temp files; emptied at open
 *   <dir>/trash/<name>.<id>                 deleted sets on their way out; emptied at open
 *   <dir>/broken/<name>.<id>                sets that failed their checksum or import at load,
 *                                           moved aside (never silently dropped)
 *   <dir>/staged/<id>/manifest, source-...  a staged copy: contents received for set <name>
 *                                           (the manifest's) but not published under it yet
 *                                           (a cluster write waiting for its quorum, see
 *                                           "Staged copies" below); kept across a restart
 * In trash/ and broken/ the name is cut so that "<name>.<id>" fits NAME_MAX (255 bytes).
 * A set name (1..255 bytes, protocol/stp_name.h) is a plain file name, so sets/<name> is one
 * directory entry of at most NAME_MAX bytes; the root may be up to PATHCAP - 512 bytes.
 *
 * Commit protocol (every acknowledged upload is on disk before the reply):
 *   1. the upload is written to tmp/<id>.part and fsynced;
 *   2. mkdir sets/<name> (when new), rename the part to sets/<name>/source-<id>.<ext>;
 *   3. write tmp/<id>.manifest, fsync, rename it over sets/<name>/manifest (the atomic
 *      commit point: before it the old set, or none, is what a restart sees; after it the new);
 *   4. fsync sets/<name>/ and sets/ (the renames are durable), then remove the old source.
 * With a set (st_datadir_commit_set) its native file is written to tmp/<id>.native and
 * fsynced before step 2 and renamed to sets/<name>/set.native between steps 2 and 3; the file
 * records the source's name, size and CRC, so a crash between that rename and the commit
 * point leaves a native file that names a source the manifest does not: refused at start and
 * rebuilt from the committed source (nothing acknowledged is lost).
 * A failure after the commit point (an fsync in step 4, or the publish callback) rolls back:
 *   the old manifest (hard-linked to tmp/<id>.prev before the rename) is put back, or the new
 *   set removed, so a set whose commit returned an error does not appear at the next start;
 *   the native file likewise (the old one, hard-linked to tmp/<id>.prevnative, put back, or
 *   the new one removed).
 * At open: tmp/ and trash/ are emptied; a set directory without a manifest is a new set whose
 * upload was never acknowledged and is removed; files a manifest does not name are leftovers
 * of an interrupted replace and are removed; a source whose size or CRC-32 differs from its
 * manifest is moved to broken/.
 *
 * Staged copies (st_datadir_stage / _publish_staged / _drop_staged / _staged_list): a cluster
 * node keeps the new contents of a write that is not acknowledged yet beside the set it
 * replaces, which stays what sets/<name> holds and what is served. Staging builds
 * tmp/<id>.stage/ (the source renamed in, a manifest written, both fsynced) and renames it to
 * staged/<id> (fsync staged/): staged/ only ever holds complete copies. Publishing commits a
 * hard link of the staged source through the commit protocol above (its CRC-32 checked
 * against the staged manifest), then removes staged/<id>: a crash at any point leaves the old
 * set or the new one in sets/<name>, and the staged copy whole until the new one is
 * committed. Dropping renames staged/<id> into trash/. What to do with a staged copy left by a
 * crash is the caller's decision (the cluster's repair pass asks the catalogue); open leaves
 * staged/ alone.
 *
 * Manifest (text, one "key value" per line, in this order):
 *   seamtex-set 1 | name <name> | source <file> | format <ext> | bytes <n> | crc32 <8 hex> |
 *   options <import options, may be empty> | end
 *
 * Threading: commit and delete serialise on a mutex inside the datadir (the fsyncs dominate);
 * the publish callback of st_datadir_commit runs under it, so the registry sees commits in the
 * same order as the disk. Any thread may call any function.
 */
#ifndef ST_DATADIR_H
#define ST_DATADIR_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"
#include "stp_name.h"

/* The native file of a set (store/native/native.h), beside its source and manifest. */
#define ST_DATADIR_NATIVE "set.native"

typedef struct st_datadir st_datadir;

typedef struct st_manifest {
    char     name[STP_MAX_NAME + 1];
    char     source[96];     /* file name inside the set directory */
    char     format[16];     /* the extension the importer keys on: "ptx", "png", ... */
    uint64_t bytes;
    uint32_t crc;
    char     options[1024];  /* import options given at upload ("key=value ..."), may be "" */
} st_manifest;

/* Opens (creating when absent) the data dir at path and cleans tmp/ and trash/. */
int st_datadir_open(const char *path, st_datadir **out, st_error *e);

/* Closes; NULL is accepted. */
void st_datadir_close(st_datadir *d);

/* Told when a commit goes on without the set's native file (see st_datadir_commit_set): the
 * set, the file that could not be written or renamed, and why (strerror's text included). */
typedef void (*st_datadir_warn_fn)(void *arg, const char *name, const char *path,
                                   const char *why);

/* Sets the commit's warning callback (NULL: none, the default). Call it before the first
 * commit; it is not synchronised with commits in progress. */
void st_datadir_set_warn(st_datadir *d, st_datadir_warn_fn warn, void *arg);

const char *st_datadir_path(const st_datadir *d);

/* Creates a new empty upload file tmp/<id>.part (O_EXCL, mode 0600). Writes its path (up to
 * cap bytes) and returns an fd open for writing in *fd; the caller writes, then commits or
 * calls st_datadir_discard. */
int st_datadir_tmpfile(st_datadir *d, char *path, size_t cap, int *fd, st_error *e);

/* Removes an upload file that will not be committed (NULL / "" accepted). */
void st_datadir_discard(const char *tmp_path);

/* Checks an extension for use as a source format: 1..8 bytes of [a-z0-9]. */
int st_format_check(const char *fmt, st_error *e);

/* Called under the commit mutex once the set is durable; a non-zero return is returned by
 * st_datadir_commit and rolls the commit back. */
typedef int (*st_publish_fn)(void *arg, const st_manifest *m, const char *source_path);

/* Commits tmp_path (a file from st_datadir_tmpfile, complete) as set `name` with source
 * format fmt: verifies its size against bytes (the caller checked the upload's own checksum),
 * computes the CRC-32 the manifest records, fsyncs, renames, writes the manifest as above. Calls publish (may be NULL) under the mutex. On any failure
 * (publish's included) the previous set of that name, or none, is what stays on disk, and
 * tmp_path is removed. */
int st_datadir_commit(st_datadir *d, const char *name, const char *tmp_path, const char *fmt,
                      const char *options, uint64_t bytes, st_publish_fn publish, void *arg,
                      st_error *e);

/* As st_datadir_commit, and when set and *set are not NULL also writes the set's native file
 * (see the protocol above); once committed, *set is replaced by the set opened from that file
 * (mmap; the heap set is freed) before publish runs, so the registry serves the mapping. When
 * the native file cannot be written (or renamed into the set) the commit goes on without it
 * (rebuilt at next start) and the warning callback (st_datadir_set_warn) is told why. */
int st_datadir_commit_set(st_datadir *d, const char *name, const char *tmp_path, const char *fmt,
                          const char *options, uint64_t bytes, st_set **set,
                          st_publish_fn publish, void *arg, st_error *e);

/* Deletes set `name` durably (rename to trash/, fsync sets/, then remove). ST_ENOTFOUND when
 * the set has no directory. unpublish (may be NULL) runs under the mutex after the rename. */
int st_datadir_delete(st_datadir *d, const char *name,
                      int (*unpublish)(void *arg, const char *name), void *arg, st_error *e);

/* Scans sets/ as described above and calls load(arg, manifest, source_path) for each set in
 * name order. A load callback that returns ST_EBUSY ("needs another set first", e.g. a mesh
 * paired with a texture set) is called again after the others, until no progress is made. A
 * set that fails the checks or whose load callback returns another code < 0 is moved to
 * broken/<name>.<time> and reported through report (may be NULL) with the reason; ST_ENOMEM or
 * ST_EIO (from the checks or the callback) says nothing about the set: it is left in place and
 * the load stops with that code. Returns the number of sets loaded, or a negative code.
 * It is st_datadir_load_sets with no_native set (one scan loop serves both). */
int st_datadir_load(st_datadir *d, st_publish_fn load, void *arg,
                    void (*report)(void *arg, const char *name, const char *why), st_error *e);

/* How st_datadir_load_sets turns set dirs into published sets. */
typedef struct st_datadir_loader {
    void *arg;
    /* imports a source into a new heap set (*out); ST_EBUSY: call again after the others */
    int (*import)(void *arg, const st_manifest *m, const char *source_path, st_set **out,
                  st_error *e);
    /* publishes set (ownership passes, also on failure) */
    int (*publish)(void *arg, const st_manifest *m, st_set *set, st_error *e);
    /* a set moved to broken/ or cleaned away, and why (may be NULL) */
    void (*report)(void *arg, const char *name, const char *why);
    /* information: a native file built / rebuilt / refused, progress ("" name) (may be NULL) */
    void (*note)(void *arg, const char *name, const char *what);
    unsigned native_flags;   /* st_native_open flags (ST_NATIVE_VERIFY: texel CRCs too) */
    int      no_native;      /* 1: ignore native files, import every source (as before them) */
    int     *built;          /* may be NULL: gets the number of native files written */
} st_datadir_loader;

/* The start-up scan with native files: cleans up as st_datadir_load, then per set maps
 * sets/<name>/set.native when it is there, passes its checks (native.h) and names the
 * manifest's source (size, CRC, file name); the source's size is checked, its bytes are not
 * read (with ST_NATIVE_VERIFY in native_flags they are: CRC-32 against the manifest, and every
 * native texel CRC). Otherwise (no native file: a data dir written before native files, i.e. the upgrade;
 * or a refused one, which is moved to broken/<name>.<id>.native and reported) the source is
 * checked whole (CRC) and imported, its native file written (tmp, fsync, rename, fsync) and
 * the set served from it. A set whose source is bad or does not import is moved to broken/.
 * Returns the number of sets published, or a negative code when sets/ cannot be read or a
 * set fails for a reason that says nothing about it (ST_ENOMEM, ST_EIO: the set is left in
 * place, not moved to broken/, and the load stops, as st_datadir_load). Not a set, nor a
 * reason to stop: an entry of sets/ that is not a directory (moved to broken/ and reported), a
 * set whose directory or manifest this process may not read (EACCES: left in place, reported,
 * not loaded), a manifest whose source file is missing (the set moved to broken/). */
int st_datadir_load_sets(st_datadir *d, const st_datadir_loader *L, st_error *e);

/* Stages tmp_path (complete, from st_datadir_tmpfile) as new contents for set name (see
 * "Staged copies"): checks its size against bytes, records its CRC-32, makes it durable under
 * staged/<id>; the id (at most 63 bytes of [0-9a-f-]) goes to id_out. tmp_path is gone
 * afterwards (moved, or removed on failure). Nothing under sets/ changes. */
int st_datadir_stage(st_datadir *d, const char *name, const char *tmp_path, const char *fmt,
                     const char *options, uint64_t bytes, char *id_out, size_t cap, st_error *e);

/* The manifest of staged copy id (m->name: the set it is for) and, when source is not NULL,
 * the path of its source file. ST_ENOTFOUND when it is gone. */
int st_datadir_staged_read(st_datadir *d, const char *id, st_manifest *m, char *source,
                           size_t cap, st_error *e);

/* Commits staged copy id as its set (st_datadir_commit_set's protocol and arguments: set may
 * be NULL, publish runs under the commit mutex), then removes the staged copy. On failure the
 * staged copy stays and sets/<name> is as it was; ST_ENOTFOUND when the staged copy is gone
 * (published or dropped by another caller). */
int st_datadir_publish_staged(st_datadir *d, const char *id, st_set **set,
                              st_publish_fn publish, void *arg, st_error *e);

/* Removes staged copy id durably (ST_ENOTFOUND when it is gone). */
int st_datadir_drop_staged(st_datadir *d, const char *id, st_error *e);

typedef struct st_datadir_staged {
    char        id[64];
    st_manifest m;
    int64_t     mtime_ms;   /* when it was staged (its manifest's mtime, wall clock ms) */
} st_datadir_staged;

/* The staged copies (*out malloc'ed, the caller frees it). One whose manifest cannot be read
 * is moved to broken/staged.<id>.<id> and reported (report may be NULL). */
int st_datadir_staged_list(st_datadir *d, st_datadir_staged **out, size_t *count,
                           void (*report)(void *arg, const char *id, const char *why),
                           void *arg, st_error *e);

/* Reads and checks one manifest file. */
int st_manifest_read(const char *path, st_manifest *m, st_error *e);

/* CRC-32 (zlib's polynomial) of a whole file; *bytes gets its size. */
int st_file_crc(const char *path, uint64_t *bytes, uint32_t *crc, st_error *e);

#endif
