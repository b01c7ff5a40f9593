/* store/native/native.h - the native set file: a set laid out on disk exactly as the sampler
 * reads it, opened by mmap (read-only, shared) with no copy and no decode.
 *
 * Owns: the file format below, writing a set as one (native_write.c) and opening one as a set
 * whose face table, level offsets and texel arena point into the mapping (native_read.c).
 * Does not own: where the file lives and when it is written (service/datadir.c), importing
 * sources (import/), the memory budget (the daemon releases cold mappings, server/).
 *
 * Format, version 1. Little-endian, fixed width, every section page-aligned (4096 bytes) and
 * checksummed with CRC-32C (util/crc32c.h). Everything is validated before use: the header's
 * own CRC, every section's bounds (page-aligned, inside the file, no overlap) and size, the
 * face table against the layout set.c would build (sizes, level counts, level offsets equal to
 * the canonical layout and inside the arena, adjacency and corner faces in range), metadata and
 * extension records entry by entry. The CRCs of the small sections (faces, levels, metadata,
 * extension) are checked at every open; the texel section's CRC is written always and checked
 * only with ST_NATIVE_VERIFY, because reading every texel at start is what the file exists to
 * avoid (a restart maps thousands of sets in seconds). The data dir checks it when it rebuilds
 * or when asked (seamtexd --verify-native); sampling a flipped texel bit cannot go out of
 * bounds, it only returns a wrong value.
 *
 * Header page (page 0):
 *   OFFSET  SIZE  DESCRIPTION
 *   0       8     magic "STNATIVE"
 *   8       4     format version (1)
 *   12      4     page size, the section alignment (4096)
 *   16      8     file size in bytes (a multiple of 4096)
 *   24      4     section count n (3..ST_NATIVE_MAX_SECTIONS)
 *   28      4     flags (0)
 *   32      4     face count (st_set_info.nfaces, 1..ST_MAX_FACES)
 *   36      1     channels (1..4)
 *   37      1     data type (st_dtype: 0 u8, 1 u16, 2 half, 3 float)
 *   38      1     alpha channel (int8, -1 none)
 *   39      1     set kind (st_kind: 0 per-face, 1 cube, 2 atlas, 3 BC1)
 *   40      1     colour space (0 linear, 1 sRGB)
 *   41      1     premultiplied (0/1)
 *   42      1     Ptex border mode u (0 clamp, 1 black, 2 periodic)
 *   43      1     Ptex border mode v
 *   44      1     Ptex mesh type (0 quad, 1 triangle)
 *   45      1     extension kind (st_ext_kind: 0 none, 1 atlas, 2 BC1, 3 Ptex resolution data)
 *   46      2     reserved (0)
 *   48      8     level offset count (sum of every face's nlevels)
 *   56      8     texel arena bytes
 *   64      8     source bytes (the manifest's: ties this file to its source)
 *   72      4     source CRC-32 (zlib's, the manifest's)
 *   76      4     reserved (0)
 *   80      96    source file name (NUL-padded, "" when none)
 *   176     848   reserved (0)
 *   1024    32*n  section table, one entry per section:
 *                   +0  4  section id (1 faces, 2 levels, 3 metadata, 4 extension, 5 texels)
 *                   +4  4  reserved (0)
 *                   +8  8  offset (a multiple of 4096, >= 4096)
 *                   +16 8  size in bytes
 *                   +24 4  CRC-32C of those size bytes
 *                   +28 4  reserved (0)
 *   4092    4     CRC-32C of bytes 0..4091
 *
 * Sections, each starting on a page, zero-padded to the next page; ids 1, 2, 5 are required,
 * each id at most once:
 *   1 faces:    nfaces records of 64 bytes, st_face of set.h as the sampler reads it:
 *                 +0 w u32, +4 h u32, +8 ulog2 u8, +9 vlog2 u8, +10 nlevels u8, +11 flags u8,
 *                 +12 lvl u32 (index of level 0 in the level offsets), +16 adjface i32[4],
 *                 +32 adjedge u8[4], +36 cornerface i32[4], +52 cornercorner u8[4],
 *                 +56 valence u8[4], +60 reserved u32
 *   2 levels:   u64 byte offset into the texel arena per (face, level), face by face
 *   3 metadata: u32 count, then per entry: u32 key bytes k (with its NUL), u8 type (Ptex:
 *               0 string, 1 int8, 2 int16, 3 int32, 4 float, 5 double), 3 bytes 0, u32 element
 *               count, u32 data bytes d, the k key bytes, the d data bytes, 0-padded to 4
 *   4 extension (by the header's extension kind):
 *       BC1 (2):   8 bytes st_bc1_ext (src_kind, src_nchan, src_alpha, punchthrough, level,
 *                  seam_mode, 2 reserved)
 *       Ptex (3):  per face u8 Ptex face flags (nfaces bytes), per face u8 stored levels
 *                  (nfaces bytes), per face its Ptex constant value (nfaces texels): what the
 *                  resolution table is built from, lazily, on the first Ptex filter call
 *       atlas (1): u32 parts (bit 0 mesh, bit 1 seam list, bit 2 chart mask), u32 mask w,
 *                  u32 mask h, 256 bytes texture name; with a mesh: u32 npos, nuv, ntri, nweld,
 *                  nfaces_src, ntri_nouv, nmat, then pos f32[3 npos], uv f32[2 nuv],
 *                  tri_pos u32[3 ntri], tri_uv u32[3 ntri], tri_weld u32[3 ntri],
 *                  tri_face u32[ntri], tri_mat u16[ntri] 0-padded to 4, materials
 *                  (128 + 512 bytes each: name, map_Kd); with seams: u32 nseams, nboundary,
 *                  nnonmanifold, nedges, ncharts, ndegenerate, nuv_border, seam records of
 *                  56 bytes (pos u32[2], tri u32[2], edge u8[2], winding i8[2], mirrored u8,
 *                  3 bytes 0, uv f32[2][2][2]), boundary then non-manifold records of 20 bytes
 *                  (pos u32[2], tri u32, edge u8, 3 bytes 0, count u32), tri_chart u32[ntri];
 *                  with a mask: mask w * mask h bytes
 *   5 texels:   the arena, texel_bytes bytes (set.h: levels of every face, texels interleaved
 *               by channel; BC1 blocks for a BC1 set), followed in the file by at least 64
 *               zero bytes (the filters load 16 bytes at a time at the arena's end)
 *
 * Ownership: st_native_open returns a set the caller frees with st_set_free, which unmaps it.
 * The mapped arrays are read-only: nothing may write into such a set (st_set_build_mips, the
 * eager Ptex table attach); its Ptex table is lazy (ptexres.h).
 */
#ifndef ST_NATIVE_H
#define ST_NATIVE_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"

#define ST_NATIVE_MAGIC        "STNATIVE"
#define ST_NATIVE_VERSION      1u
#define ST_NATIVE_PAGE         4096u
#define ST_NATIVE_MAX_SECTIONS 8u
#define ST_NATIVE_SLACK        64u     /* zero bytes after the arena in the file */

enum st_native_section {
    ST_NSEC_FACES = 1,
    ST_NSEC_LEVELS = 2,
    ST_NSEC_META = 3,
    ST_NSEC_EXT = 4,
    ST_NSEC_TEXELS = 5
};

enum st_native_flags {
    ST_NATIVE_VERIFY = 1u    /* also check the texel section's CRC-32C (reads every byte) */
};

/* What a native file records of the source it was built from (the data dir's manifest). */
typedef struct st_native_source {
    uint64_t bytes;
    uint32_t crc;
    char     name[96];
} st_native_source;

/* Writes s as a native file to the open file descriptor fd (from its current position, which
 * must be 0; nothing is fsynced: the caller's commit protocol does that). src may be NULL. */
int st_native_write_fd(int fd, const st_set *s, const st_native_source *src, st_error *e);

/* The size in bytes of the native file st_native_write_fd would write for s (exact: the same
 * layout; the small sections are serialised to measure them). Builds every level of a
 * deferred Ptex import first, as the writer does. The daemon promises this many bytes of
 * free disk before it writes the file (docs/daemon.md "Free space for uploads"). */
int st_native_size(const st_set *s, uint64_t *bytes, st_error *e);

/* Writes s to path crash-safely: "<path>.tmp", fsync, rename, fsync of the folder. */
int st_native_write(const char *path, const st_set *s, const st_native_source *src,
                    st_error *e);

/* Opens the native file at path: checks it (see above; flags ST_NATIVE_VERIFY adds the texel
 * CRC), maps it and returns a set sampling from the mapping. *src (may be NULL) gets what the
 * file records of its source. Errors: ST_ENOTFOUND (no file), ST_EFORMAT (truncated, bad
 * magic / version / offsets / sizes / face table, the message says which), ST_ECORRUPT (a
 * CRC), ST_EIO, ST_ENOMEM. */
int st_native_open(const char *path, unsigned flags, st_native_source *src, st_set **out,
                   st_error *e);

/* As st_native_open on an open file descriptor, which the set keeps (closed by st_set_free,
 * or here on failure). */
int st_native_open_fd(int fd, unsigned flags, st_native_source *src, st_set **out,
                      st_error *e);

/* Residency: what the memory budget counts of a mapping and how it lets go of it
 * (native_resident.c). A meter says which count is used:
 *   ST_NATIVE_COUNT_MAPPED (pagemap_fd >= 0, /proc/self/pagemap open): the mapping's pages
 *     present in THIS process's page tables - what the process holds (its RssFile share). A
 *     release unmaps them (madvise MADV_COLD, which puts them at the cold end of the kernel's
 *     reclaim lists, then MADV_DONTNEED) and leaves the file in the page cache: the next sample
 *     faults back what it touches from memory (a minor fault) while the page cache holds it.
 *     Another process mapping the same file counts only its own pages.
 *   ST_NATIVE_COUNT_CACHED (pagemap_fd < 0: /proc/self/pagemap cannot be read): the file's
 *     pages in the page cache, as mincore(2) reports them for a file the caller owns or may
 *     write (for any other file the kernel reports only the caller's mapped pages). A release
 *     also drops them from the page cache (posix_fadvise DONTNEED) - without that the count
 *     would not go down - so the next sample reads them from the disk.
 * The meter holds one file descriptor; its owner closes it (st_native_meter_close). */
typedef enum { ST_NATIVE_COUNT_MAPPED = 0, ST_NATIVE_COUNT_CACHED = 1 } st_native_count;

typedef struct st_native_meter {
    int pagemap_fd;   /* /proc/self/pagemap, or -1: count the page cache (mincore) */
} st_native_meter;

/* Opens /proc/self/pagemap; returns the count the meter gives (CACHED when it cannot). */
st_native_count st_native_meter_open(st_native_meter *m);
void st_native_meter_close(st_native_meter *m);
st_native_count st_native_meter_count(const st_native_meter *m);

/* Bytes of the set's mapping resident as the meter counts them (0 for a heap set). A pagemap
 * read that fails counts that part with mincore (an upper bound: mapped pages are cached). */
size_t st_native_resident(const st_set *s, const st_native_meter *m);

/* Releases a mapped set's pages as the meter's count says (above); the next sample faults in
 * only the pages it touches, with the same bytes. Returns the bytes that were resident. */
size_t st_native_release(const st_set *s, const st_native_meter *m);

#endif
