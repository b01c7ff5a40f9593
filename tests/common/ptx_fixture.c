/* tests/common/ptx_fixture.c - see ptx_fixture.h. */
#include "ptx_fixture.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "defaultset.h"
#include "ptex.h"

void *st_fixture_default_ptx(size_t *len, int tint)
{
    st_set *s = NULL;
    st_error e;
    if (st_default_set(&s, &e) != 0) {
        fprintf(stderr, "default set: %s\n", e.msg);
        return NULL;
    }
    if (tint >= 0) {
        uint8_t *t = st_face_level(s, 0, 0);
        size_t n = (size_t)s->faces[0].w * s->faces[0].h * st_texel_size(s);
        for (size_t i = 0; i < n; i++)
            t[i] = (uint8_t)(tint * 37 + i);
        st_set_build_mips(s, 0);
    }
    void *buf = NULL;
    if (st_ptex_write_mem(s, &buf, len, &e) != 0) {
        fprintf(stderr, "ptex write: %s\n", e.msg);
        buf = NULL;
    }
    st_set_free(s);
    return buf;
}

st_set *st_fixture_rgba8_faces(uint32_t n)
{
    st_set_info info;
    memset(&info, 0, sizeof info);
    info.nfaces = 4;
    info.nchan = 4;
    info.dtype = ST_DT_U8;
    info.alpha_chan = 3;
    st_face_desc fd[4];
    memset(fd, 0, sizeof fd);
    for (int f = 0; f < 4; f++) {
        fd[f].w = fd[f].h = n;
        for (int k = 0; k < 4; k++)
            fd[f].adjface[k] = -1;
    }
    st_set *s = NULL;
    st_error e;
    st_error_clear(&e);
    return st_set_create(&info, fd, 0, &s, &e) == 0 ? s : NULL;
}

void *st_fixture_uniform_ptx(size_t *len)
{
    st_set *s = st_fixture_rgba8_faces(32);
    if (!s)
        return NULL;
    st_error e;
    st_error_clear(&e);
    for (size_t i = 0; i < s->texel_bytes; i++)
        s->texels[i] = (uint8_t)(i * 13 + (i >> 7));
    st_set_build_mips(s, UINT32_MAX);
    void *buf = NULL;
    if (st_ptex_write_mem(s, &buf, len, &e) != 0)
        buf = NULL;
    st_set_free(s);
    return buf;
}
