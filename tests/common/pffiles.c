/* tests/common/pffiles.c - see pffiles.h. */
#include "pffiles.h"

#include <stdio.h>

#include "ptex.h"
#include "testdata.h"

int st_pf_read_shared(const char *rel, char *path, size_t cap, st_set **s)
{
    *s = NULL;
    if (st_test_data_path(path, cap, rel) != 0)
        return 0;
    st_error e = {0};
    if (st_ptex_read_file(path, 0, s, &e) != 0) {
        fprintf(stderr, "%s: %s\n", path, e.msg);
        return -1;
    }
    return 1;
}

long st_pf_each_file(const char *const *files, size_t n, st_pf_file_fn fn, void *ctx,
                     int *found)
{
    long compared = 0;
    *found = 0;
    for (size_t i = 0; i < n; i++) {
        char path[1024];
        st_set *s;
        int r = st_pf_read_shared(files[i], path, sizeof path, &s);
        if (r <= 0) {
            if (r < 0)
                return -1;
            continue;
        }
        (*found)++;
        long c = fn(s, ctx, path);
        st_set_free(s);
        if (c < 0)
            return -1;
        compared += c;
    }
    return compared;
}

/* A face the file made constant: flagged so, and its levels all start at one offset (they
 * share its one texel: set.c's layout), so it has no level data to fall back on. */
static int holds_one_texel(const st_set *s, uint32_t f)
{
    const st_face *F = &s->faces[f];
    return (F->flags & ST_FACE_CONSTANT) && F->nlevels >= 2 &&
           s->level_off[F->lvl] == s->level_off[F->lvl + 1];
}

void st_pf_flag_faces(st_set *s, uint8_t flag, uint8_t clear)
{
    for (uint32_t f = 0; f < s->info.nfaces; f++) {
        if (!holds_one_texel(s, f))
            s->faces[f].flags &= (uint8_t)~clear;
        if (f % 10 == 3)
            s->faces[f].flags |= flag;
    }
}
