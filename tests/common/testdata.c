/* tests/common/testdata.c - shared-data lookup and scratch directories for tests (see
 * testdata.h). */
#include "testdata.h"

#include <dirent.h>
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
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

int st_test_dir_entries(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    int n = 0;
    struct dirent *de;
    while ((de = readdir(d)))
        if (strcmp(de->d_name, ".") && strcmp(de->d_name, ".."))
            n++;
    closedir(d);
    return n;
}

void *st_test_read_file(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    long n = -1;
    if (fseek(f, 0, SEEK_END) == 0)
        n = ftell(f);
    rewind(f);
    char *b = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    if (b)
        b[n] = 0;
    *len = b ? (size_t)n : 0;
    return b;
}

/* Every *.ptx under <data>/sub, recursively, appended to rel (paths relative to the data dir). */
static void ptx_walk(const char *sub, char (*rel)[512], int *n, int max)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", st_test_data_dir(), sub);
    DIR *d = opendir(path);
    if (!d)
        return;
    struct dirent *de;
    while ((de = readdir(d))) {
        if (de->d_name[0] == '.')
            continue;
        char r[512];
        if (snprintf(r, sizeof r, "%s/%s", sub, de->d_name) >= (int)sizeof r)
            continue;
        snprintf(path, sizeof path, "%s/%s", st_test_data_dir(), r);
        struct stat sb;
        if (stat(path, &sb))
            continue;
        size_t l = strlen(de->d_name);
        if (S_ISDIR(sb.st_mode))
            ptx_walk(r, rel, n, max);
        else if (l > 4 && !strcmp(de->d_name + l - 4, ".ptx") && *n < max)
            memcpy(rel[(*n)++], r, sizeof r);
    }
    closedir(d);
}

static int cmp_rel(const void *a, const void *b)
{
    return strcmp((const char *)a, (const char *)b);
}

int st_test_ptx_files(char (*rel)[512], int max)
{
    int n = 0;
    ptx_walk("ptex-ref", rel, &n, max);
    ptx_walk("ptx", rel, &n, max);
    qsort(rel, (size_t)n, sizeof rel[0], cmp_rel);
    return n;
}
