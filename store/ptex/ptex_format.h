/* store/ptex/ptex_format.h - the Ptex file format (version 1, any minor version) as seamtex reads
 * and writes it. Private to ptex_read.c and ptex_write.c; everything little-endian.
 *
 * Owns: the byte layout (offset tables below) and tiny decoders for it. Does not own: any
 * policy (what is refused, how sets are built) - that is in the reader and writer.
 *
 * File = Header | ExtHeader | FaceInfo (zip) | ConstData (zip) | LevelInfo | Level data ... |
 *        MetaData (zip) | 8 zero bytes | LargeMetaData header (zip) | LargeMetaData blocks |
 *        Edit records ...
 * Every section follows the previous one directly; its size is in the header. "zip" means one
 * zlib (deflate with zlib header) stream whose inflated size is known from the header.
 *
 * Header (64 bytes)
 *   OFFSET SIZE DESCRIPTION
 *        0    4 magic "Ptex" (0x78657450 read as little-endian u32)
 *        4    4 version, must be 1
 *        8    4 mesh type: 0 triangle, 1 quad
 *       12    4 data type: 0 u8, 1 u16, 2 half, 3 float (= st_dtype)
 *       16    4 alpha channel (s32), -1 or >= nchannels: none
 *       20    2 nchannels
 *       22    2 nlevels (level 0 + stored reductions)
 *       24    4 nfaces
 *       28    4 extheadersize (0 in the oldest files; 24 in 2009 files; 40 now)
 *       32    4 faceinfosize (zipped bytes)
 *       36    4 constdatasize (zipped bytes)
 *       40    4 levelinfosize (bytes, = 16 * nlevels)
 *       44    4 minor version (0 in old files)
 *       48    8 leveldatasize (bytes of all levels)
 *       56    4 metadatazipsize
 *       60    4 metadatamemsize (inflated)
 *
 * ExtHeader (extheadersize bytes; missing fields read as 0)
 *   OFFSET SIZE DESCRIPTION
 *        0    2 u border mode: 0 clamp, 1 black, 2 periodic
 *        2    2 pad
 *        4    2 v border mode
 *        6    2 edge filter mode: 0 none, 1 tanvec
 *        8    4 lmdheaderzipsize (large metadata header, zipped)
 *       12    4 lmdheadermemsize
 *       16    8 lmddatasize (bytes of all large metadata blocks)
 *       24    8 editdatasize
 *       32    8 editdatapos (absolute; 0 in files older than the field: scan to EOF)
 *
 * FaceInfo (20 bytes per face, inflated from faceinfosize bytes, nfaces records)
 *   OFFSET SIZE DESCRIPTION
 *        0    1 ulog2 (s8)
 *        1    1 vlog2 (s8)
 *        2    1 adjedges: 2 bits per edge, edge e at bits 2e..2e+1
 *        3    1 flags: 1 constant, 2 has edits, 4 neighbourhood constant, 8 subface
 *        4   16 adjfaces[4] (s32, -1 = none), edges bottom, right, top, left; a triangle
 *                 face has three edges, 0 (v = 0), 1 (u + v = 1), 2 (u = 0): adjfaces[3] is
 *                 -1, adjedges uses bits 0..5, the face is square (ulog2 == vlog2) and its
 *                 blocks hold the packed triangle layout of core/trilevel.h
 *
 * ConstData: nfaces pixels (pixel = nchannels * datasize, channels interleaved), the face's
 *   value when constant, else its average (Ptex serves it for the 1x1 resolution).
 *
 * LevelInfo (16 bytes per level)
 *   OFFSET SIZE DESCRIPTION
 *        0    8 leveldatasize (this level: header + blocks)
 *        8    4 levelheadersize (zipped)
 *       12    4 nfaces in this level
 *
 * Level L: a zipped array of nfaces FaceDataHeaders (u32: bits 0..29 block size, 30..31
 *   encoding 0 constant, 1 zipped, 2 diff-zipped, 3 tiled) then the blocks back to back.
 *   Level 0 lists every face by face id. Level L >= 1 holds the reduction to
 *   (ulog2-L, vlog2-L) of the first nfaces faces in "rfaceid" order: face ids stably sorted
 *   by min(ulog2, vlog2) descending (a constant face counts as 1).
 *   constant   : one pixel (block size = pixel size)
 *   zipped     : inflates to u*v pixels stored planar: all of channel 0 (rows of u), then 1...
 *   diffzipped : the same, u8/u16 only, delta-coded (x[i] - x[i-1], mod 2^n) in one run
 *                over the whole planar block (the run continues from one plane to the next)
 *   tiled      : 2 bytes tile res (s8 ulog2, s8 vlog2), u32 tileheadersize, zipped
 *                FaceDataHeaders of the tiles (row-major, u fastest), then the tile blocks
 *                (constant, zipped or diff-zipped), back to back.
 *
 * MetaData (inflated metadatamemsize bytes) and the large-metadata header: records of
 *   u8 keysize (with NUL) | key | u8 type (0 string, 1 s8, 2 s16, 3 s32, 4 float, 5 double) |
 *   u32 datasize | data               (small: data inline)
 *   u8 keysize | key | u8 type | u32 datasize | u32 zipsize   (large: data in its own zip
 *   block, blocks back to back after the large-metadata header)
 *
 * Edit records: u8 type (0 face data, 1 metadata) | u32 size of what follows | payload.
 *   face data: u32 faceid | FaceInfo (20) | FaceDataHeader (4) | const pixel | block
 *   metadata : u32 zipsize | u32 memsize | zipped metadata records
 *   A record with size 0 ends the list. An edited face's stored reductions are ignored.
 */
#ifndef ST_PTEX_FORMAT_H
#define ST_PTEX_FORMAT_H

#include <stdint.h>
#include <string.h>

#define PTX_MAGIC            0x78657450u
#define PTX_HEADER_SIZE      64u
#define PTX_EXTHEADER_SIZE   40u
#define PTX_FACEINFO_SIZE    20u
#define PTX_LEVELINFO_SIZE   16u
#define PTX_FDH_SIZE         4u
#define PTX_EDIT_FACE_SIZE   28u   /* faceid + FaceInfo + FaceDataHeader */
#define PTX_EDIT_META_SIZE   8u
#define PTX_TILE_SIZE        65536 /* target uncompressed tile size of the Ptex writer */
#define PTX_META_THRESHOLD   1024  /* larger metadata go to large-metadata blocks */
#define PTX_MESH_TRIANGLE    0u    /* header mesh type (seamtex's st_meshtype numbers differ) */
#define PTX_MESH_QUAD        1u
#define PTX_MAX_ZIP_RATIO    1032u
#define PTX_MAX_LEVELS_W     17    /* level info entries the writer may emit (ulog2 <= 15, +1) */ /* deflate cannot expand more than this (+ a constant) */

enum { PTX_ENC_CONSTANT = 0, PTX_ENC_ZIPPED = 1, PTX_ENC_DIFFZIPPED = 2, PTX_ENC_TILED = 3 };
enum { PTX_FLAG_CONSTANT = 1, PTX_FLAG_HASEDITS = 2, PTX_FLAG_NBCONSTANT = 4,
       PTX_FLAG_SUBFACE = 8 };
enum { PTX_EDIT_FACEDATA = 0, PTX_EDIT_METADATA = 1 };

static inline uint16_t ptx_rd16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }
static inline uint32_t ptx_rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint64_t ptx_rd64(const uint8_t *p)
{
    return (uint64_t)ptx_rd32(p) | (uint64_t)ptx_rd32(p + 4) << 32;
}
static inline void ptx_wr16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static inline void ptx_wr32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}
static inline void ptx_wr64(uint8_t *p, uint64_t v)
{
    ptx_wr32(p, (uint32_t)v);
    ptx_wr32(p + 4, (uint32_t)(v >> 32));
}

/* One decoded FaceInfo record. */
typedef struct ptx_faceinfo {
    int8_t   ulog2, vlog2;
    uint8_t  adjedges, flags;
    int32_t  adjfaces[4];
} ptx_faceinfo;

static inline void ptx_faceinfo_decode(const uint8_t *p, ptx_faceinfo *fi)
{
    fi->ulog2 = (int8_t)p[0];
    fi->vlog2 = (int8_t)p[1];
    fi->adjedges = p[2];
    fi->flags = p[3];
    for (int e = 0; e < 4; e++)
        fi->adjfaces[e] = (int32_t)ptx_rd32(p + 4 + 4 * e);
}
static inline void ptx_faceinfo_encode(uint8_t *p, const ptx_faceinfo *fi)
{
    p[0] = (uint8_t)fi->ulog2;
    p[1] = (uint8_t)fi->vlog2;
    p[2] = fi->adjedges;
    p[3] = fi->flags;
    for (int e = 0; e < 4; e++)
        ptx_wr32(p + 4 + 4 * e, (uint32_t)fi->adjfaces[e]);
}

#endif
