/* tests/common/testdata.c - shared-data lookup and scratch directories for tests (see
 * testdata.h). */
#include "testdata.h"

#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

const char *st_test_data_dir(void)
{
    const char *d = getenv("SEAMTEX_DATA");
    return d && *d ? d : "../shared/data";
}

int st_test_data_path(char *buf, size_t cap, const char *rel)
{
    snprintf(buf, cap, "%s/%s", st_test_data_dir(), rel);
    if (access(buf, R_OK)) {
        printf("# SEAMTEX_DATA (%s) has no %s: skipped\n", st_test_data_dir(), rel);
        fflush(stdout);
        return -1;
    }
    return 0;
}

int st_test_mkdtemp(char *buf, size_t cap, const char *tag)
{
    if ((size_t)snprintf(buf, cap, "/tmp/seamtex_%s_XXXXXX", tag) >= cap)
        return -1;
    return mkdtemp(buf) ? 0 : -1;
}

static int rm_one(const char *path, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb;
    (void)flag;
    (void)ftw;
    return remove(path);
}

int st_test_rmtree(const char *dir)
{
    return nftw(dir, rm_one, 16, FTW_DEPTH | FTW_PHYS);
}
