/* tests/common/ptx_fixture.c - see ptx_fixture.h. */
#include "ptx_fixture.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <zlib.h>

#include "defaultset.h"
#include "ptex.h"
#include "ptex_format.h"

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

int st_fixture_corrupt_reduction(uint8_t *b, size_t len, int what)
{
    if (len < PTX_HEADER_SIZE || ptx_rd16(b + 22) < 2)
        return -1;
    uint64_t ext = ptx_rd32(b + 28), fisize = ptx_rd32(b + 32), cdsize = ptx_rd32(b + 36);
    uint64_t lipos = PTX_HEADER_SIZE + ext + fisize + cdsize, ldpos = lipos + ptx_rd32(b + 40);
    if (lipos + 2 * PTX_LEVELINFO_SIZE > len)
        return -1;
    uint64_t l1 = ldpos + ptx_rd64(b + lipos);
    uint32_t hsize = ptx_rd32(b + lipos + PTX_LEVELINFO_SIZE + 8);
    uint8_t fdh[4096];
    uLongf fl = sizeof fdh;
    if (l1 + hsize > len || uncompress(fdh, &fl, b + l1, hsize) != Z_OK || fl < 4)
        return -1;
    uint32_t h0 = ptx_rd32(fdh), size = h0 & 0x3fffffffu;
    uint64_t blk = l1 + hsize;
    if ((h0 >> 30 != PTX_ENC_ZIPPED && h0 >> 30 != PTX_ENC_DIFFZIPPED) || size <= 12 ||
        blk + size > len)
        return -1;
    b[what == 0 ? blk + size / 2 : blk + size - 1] ^= what == 0 ? 0x24 : 0x01;
    return 0;
}
