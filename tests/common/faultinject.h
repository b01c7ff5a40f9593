/* tests/common/faultinject.h - SQLite-style fault injection for in-process store tests: fail
 * the Nth allocation / open / write / fsync / rename after arming, with ENOMEM, EIO, ENOSPC or
 * a short write.
 *
 * Owns: the counters and the __wrap_* functions of faultinject.c. A binary uses them by being
 * linked with -Wl,--wrap=<fn> for every function in FI_WRAPPED (tests/module.mk does that for
 * test_faults_*): --wrap redirects only the calls made by objects linked into that binary (the
 * store archives, the test), not those inside libc, zlib or OpenImageIO, which is the scope we
 * want: the store's own error paths. Does not own: what a failure must lead to (the tests).
 *
 * Kinds: FI_ALLOC (malloc calloc realloc strdup aligned_alloc: NULL, errno ENOMEM;
 * posix_memalign: ENOMEM returned), FI_OPEN (open openat
 * fopen), FI_WRITE (write pwrite), FI_FSYNC (fsync fdatasync), FI_RENAME (rename renameat link
 * mkdir). Only one kind counts at a time; single shot: after the Nth call fails, later calls
 * succeed (SQLite's "transient" mode), unless fi_arm's persist is set (every call from the Nth
 * on fails: SQLite's "persistent" mode, a full disk).
 *
 * Usage, the loop: for n = 1, 2, ...: fi_arm(kind, n, how, 0); run the operation; fi_disarm();
 * check the outcome; stop when !fi_fired() (the operation finished before its nth call).
 * Not thread-safe in intent (counters are atomic, but tests arm around single-threaded code).
 */
#ifndef ST_FAULTINJECT_H
#define ST_FAULTINJECT_H

typedef enum fi_kind { FI_ALLOC, FI_OPEN, FI_WRITE, FI_FSYNC, FI_RENAME, FI_NKINDS } fi_kind;
typedef enum fi_how { FI_EIO, FI_ENOSPC, FI_SHORT, FI_ENOMEM } fi_how;

#define FI_WRAPPED "malloc calloc realloc strdup aligned_alloc posix_memalign open openat fopen write pwrite fsync " \
                   "fdatasync rename renameat link mkdir"

/* Counts calls of kind from now on; the nth (n >= 1) fails as how says (FI_ALLOC always
 * fails with NULL/ENOMEM; FI_SHORT on a non-write kind fails with EIO). n = 0 counts only. */
void fi_arm(fi_kind kind, unsigned long n, fi_how how, int persist);
void fi_disarm(void);
/* Calls of the armed kind counted since fi_arm. */
unsigned long fi_count(void);
/* 1 when the nth call was reached (and failed) since fi_arm. */
int fi_fired(void);
const char *fi_kind_name(fi_kind k);
const char *fi_how_name(fi_how h);

#endif
