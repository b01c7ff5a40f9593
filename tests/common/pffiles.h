/* tests/common/pffiles.h - the shared .ptx files a Ptex filter test runs over, one set at a
 * time, and the face flags such a test sets after the set is made (session 19; for
 * test_ptexfilter_lean3, and any filter test that loops over shared files).
 *
 * Owns nothing past a call: each set is read, handed to the callback and freed.
 */
#ifndef ST_TEST_PFFILES_H
#define ST_TEST_PFFILES_H

#include <stddef.h>
#include <stdint.h>

#include "set.h"

/* The shared file rel (under SEAMTEX_DATA) read into *s (the caller frees it), its full path
 * in path (cap bytes): 1 when read, 0 when the data folder does not have it, -1 (the
 * reader's message on stderr) when it does not read. */
int st_pf_read_shared(const char *rel, char *path, size_t cap, st_set **s);

/* fn(set, ctx, path) for each of the n files (relative to the shared data folder) that the
 * folder has, each read into its own set (freed after); fn returns how many queries it
 * compared, or -1 on a failure. Returns the sum, or -1 after a read error (printed to
 * stderr) or a failing fn; *found is the number of files read. */
typedef long (*st_pf_file_fn)(st_set *s, void *ctx, const char *path);
long st_pf_each_file(const char *const *files, size_t n, st_pf_file_fn fn, void *ctx,
                     int *found);

/* Every tenth face (from the fourth) gets flag, and clear is removed from every face but
 * those the file made constant (they hold one texel: without the flag they would be read as
 * whole faces); set after the resolution table and the corners are made, so both paths read
 * the same data. */
void st_pf_flag_faces(st_set *s, uint8_t flag, uint8_t clear);

#endif
