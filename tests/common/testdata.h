/* tests/common/testdata.h - where tests and benchmarks find the shared assets and scratch
 * space. The shared data folder is $SEAMTEX_DATA (tests/run.sh and tests/bench/run.sh set
 * it), default ../shared/data; it is never copied into the repository. */
#ifndef ST_TESTDATA_H
#define ST_TESTDATA_H

#include <stddef.h>

/* The shared data folder ($SEAMTEX_DATA or ../shared/data). */
const char *st_test_data_dir(void);

/* Writes "<data dir>/<rel>" into buf. Returns 0 when that file is readable; otherwise prints
 * a TAP comment saying what is missing (the caller then skips) and returns -1. */
int st_test_data_path(char *buf, size_t cap, const char *rel);

/* The shared .ptx files: every *.ptx under <data dir>/ptex-ref and <data dir>/ptx, searched
 * recursively, as paths relative to the data dir ("ptx/foo/bar.ptx"), sorted; at most max.
 * Returns how many (0 when the data dir has none). */
int st_test_ptx_files(char (*rel)[512], int max);

/* Creates a fresh scratch directory /tmp/seamtex_<tag>_XXXXXX into buf; 0 or -1. */
int st_test_mkdtemp(char *buf, size_t cap, const char *tag);

/* Removes a directory tree (made by st_test_mkdtemp, mkdtemp or a daemon); 0 or -1. */
int st_test_rmtree(const char *dir);

/* Entries of a directory other than "." and ".."; 0 when it does not exist. */
int st_test_dir_entries(const char *dir);

/* Reads a whole file into a malloc'ed buffer with a NUL byte after its *len bytes (so text
 * files can be used as strings). NULL when it cannot be read. */
void *st_test_read_file(const char *path, size_t *len);

#endif
