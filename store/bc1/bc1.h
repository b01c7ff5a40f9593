/* store/bc1/bc1.h - BC1 (DXT1) encoding and decoding, BC1-resident sets, seam-aware compression
 * and DDS import/export (bc1_encode.c with bc1_fit.c, bc1_cluster.c, bc1_select.c and
 * bc1_encode_avx2.c; bc1_decode.c, bc1_set.c, bc1_seam.c, dds.c).
 *
 * Owns: the block encoder (three levels), the block decoders (exact, and the vendor variants
 * as an option), turning any stored set into an ST_KIND_BC1 set (with least-squares seam
 * masking and the seam-aware endpoint solve), DDS files of BC1 sets.
 * Does not own: sampling BC1 sets (the sampler decodes on tap with bc1_texel.h), seam geometry
 * (mesh.h finds atlas seams; seammask.h turns seams into sample points and solves), jobs
 * (the daemon runs st_bc1_compress_set in a worker and passes progress and cancel).
 *
 * Block: 8 bytes, layout in bc1_texel.h. Input of a block is 16 RGBA8 texels, row-major
 * (texel t = 4*y + x at rgba[4*t]).
 *   - Opaque input (every alpha >= 128) never uses the transparent selector: the encoder picks
 *     4-colour mode (c0 > c1) or, when it is better, 3-colour mode with selectors 0..2 only.
 *   - Input with some alpha < 128 is encoded in 3-colour mode, selector 3 (transparent black)
 *     on exactly those texels ("1-bit alpha as BC1 allows"); alpha is otherwise ignored.
 *
 * Levels: ST_BC1_FAST (principal axis bounding box, one least-squares refinement),
 * ST_BC1_HQ (iterated least squares on the exact palette, a local cluster fit, 565 rounding
 * neighbourhood search, 3-colour trial) and ST_BC1_BEST (the cluster fit over every split).
 * Figures in docs/bc1.md.
 *
 * Threading: block functions are pure (no allocation, no globals, deterministic); any number
 * of threads may call them. st_bc1_compress_set may start worker threads of its own (opts).
 */
#ifndef ST_BC1_H
#define ST_BC1_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "set.h"
#include "bc1_texel.h"

enum { ST_BC1_FAST = 0, ST_BC1_HQ = 1, ST_BC1_BEST = 2 };

/* Decoders. EXACT is the rule of bc1_texel.h (c2 = (2c0+c1)/3 truncating) and the one every
 * PSNR figure of seamtex uses. The others model hardware: */
typedef enum st_bc1_decoder {
    ST_BC1_DEC_EXACT  = 0,  /* truncating thirds and half, the reference rule */
    ST_BC1_DEC_IDEAL  = 1,  /* rounded thirds: (2c0+c1+1)/3, rounded half */
    ST_BC1_DEC_AMD    = 2,  /* (43*c0 + 21*c1 + 32) >> 6, half (c0+c1+1)>>1 */
    ST_BC1_DEC_NVIDIA = 3   /* interpolation on the 5/6-bit values, NVIDIA's rounding */
} st_bc1_decoder;

/* ---- block level (bc1_encode.c and its stages, bc1_decode.c) ---------------------------- */

/* Encodes one 4x4 block of RGBA8 texels into out[8]. level: ST_BC1_FAST, ST_BC1_HQ or
 * ST_BC1_BEST (any other value is treated as HQ). */
void st_bc1_encode_block(const uint8_t rgba[64], int level, uint8_t out[8]);

/* The same with a weight per texel (>= 0, NULL = all 1) on its squared error: what seam-aware
 * compression uses so that texels outside every chart do not take precision from the texels
 * that are seen. A block whose opaque texels all have weight 0 still gets a valid encoding
 * (the weights are then ignored for the principal axis). */
void st_bc1_encode_block_w(const uint8_t rgba[64], const float weight[16], int level,
                           uint8_t out[8]);

/* The 4-entry RGBA8 palette of endpoints c0, c1 under a decoder (pal[4*i + k]). */
void st_bc1_palette(uint16_t c0, uint16_t c1, st_bc1_decoder dec, uint8_t pal[16]);

/* Decodes one block into 16 RGBA8 texels (row-major). */
void st_bc1_decode_block(const uint8_t blk[8], st_bc1_decoder dec, uint8_t rgba[64]);

/* Encodes / decodes a whole RGBA8 image (w x h, any size >= 1, rows of `stride` bytes).
 * Blocks: ceil(w/4) x ceil(h/4), row-major; edge blocks are padded by repeating the last
 * row/column. Encoding of big images is split over `threads` threads (0 = one per core,
 * at most 64). Decoding writes w x h texels to `rgba` (stride w*4). */
int st_bc1_encode_image(const uint8_t *rgba, uint32_t w, uint32_t h, size_t stride, int level,
                        int threads, uint8_t *blocks, st_error *e);
/* The same with a weight per texel (w*h floats, row-major, stride w; NULL = all 1). */
int st_bc1_encode_image_w(const uint8_t *rgba, const float *weights, uint32_t w, uint32_t h,
                          size_t stride, int level, int threads, uint8_t *blocks, st_error *e);
void st_bc1_decode_image(const uint8_t *blocks, uint32_t w, uint32_t h, st_bc1_decoder dec,
                         uint8_t *rgba);

/* PSNR in dB of RGB (alpha ignored) between two w x h RGBA8 images; 99 when identical. */
double st_bc1_psnr_rgb(const uint8_t *a, const uint8_t *b, size_t ntexels);

/* ---- BC1-resident sets ------------------------------------------------------------------ */


/* Attaches x (malloc'ed; the set owns it from here on) as the ST_EXT_BC1 extension of s. */
void st_bc1_ext_attach(st_set *s, st_bc1_ext *x);

typedef enum st_bc1_seam_mode {
    ST_BC1_SEAM_NONE  = 0,  /* plain BC1 of the source */
    ST_BC1_SEAM_MASK  = 1,  /* least-squares seam masking, then plain BC1 */
    ST_BC1_SEAM_AWARE = 2   /* masking, then the seam-aware endpoint solve (default) */
} st_bc1_seam_mode;

typedef struct st_bc1_opts {
    int      level;         /* ST_BC1_FAST, ST_BC1_HQ or ST_BC1_BEST (default HQ) */
    int      seam_mode;     /* st_bc1_seam_mode (default ST_BC1_SEAM_AWARE) */
    float    alpha;         /* seam weight of E = Ec + alpha*Es (default 2) */
    float    seam_boost;    /* the seam-aware BC1 stage uses alpha * seam_boost (default
                               1.25, the point of the measured seam RMS / PSNR trade-off
                               curve that meets the most report targets, docs/bc1.md) */
    float    seam_rms_goal; /* while the seam-aware result's seam RMS is above this times
                               the masked texture's, its seam weight is raised 1.2x (at
                               most 8 times; default 1.1, 0 = keep alpha * seam_boost) */
    float    step;          /* seam sample spacing in texels (default 0.5) */
    int      iterations;    /* seam-aware solve / quantise / re-select rounds (default 3) */
    int      threads;       /* encoder threads, 0 = one per core */
    size_t   max_bytes;     /* cap on the output arena, 0 = ST_DEFAULT_MAX_BYTES */
} st_bc1_opts;

/* Fills the defaults above. */
void st_bc1_opts_default(st_bc1_opts *o);

/* progress(arg, fraction) is called from the calling thread with 0 <= fraction <= 1, non
 * decreasing, ending with 1 on success. */
typedef void (*st_bc1_progress_fn)(void *arg, double fraction);

/* Re-encodes every level of every face of `src` (any kind, dtype and channel count; float
 * and half are clamped to 0..1; 1 channel -> grey, 2 channels -> grey + alpha when
 * alpha_chan is 1) into a new ST_KIND_BC1 set: same faces, sizes and adjacency; level 0 from
 * the (seam-masked) texels, each further level encoded from the 2x2 box reduction of the
 * RGBA8 level above; constant faces stay one RGBA8 texel. Seams: an atlas set
 * (ST_KIND_ATLAS, mesh in ext) uses its mesh's UV seams; a per-face or cube set uses every
 * shared face edge (through the adjacency). o NULL = defaults; progress may be NULL; cancel
 * may be NULL and is read often: when it becomes non-zero the call returns ST_ECANCELED
 * promptly and frees what it made. On success *out is a new set the caller owns
 * (st_set_free). A triangle-mesh set (st_meshtype) is refused with ST_EUNSUPPORTED and
 * ST_BC1_TRIANGLE_REFUSAL (docs/bc1.md says why). */
#define ST_BC1_TRIANGLE_REFUSAL                                                                \
    "BC1 compression of a triangle-mesh set is not supported (a 4x4 block of its packed "     \
    "triangle layout mixes upright and mirrored inverted triangles of distant parts of the "   \
    "face, and seam masking follows quad edges)"
int st_bc1_compress_set(const st_set *src, const st_bc1_opts *o, st_bc1_progress_fn progress,
                        void *progress_arg, const volatile int *cancel, st_set **out,
                        st_error *e);

/* Decodes a BC1 set back into a new RGBA8 set of the source kind (ST_KIND_PERFACE for
 * per-face, CUBE for cube, ATLAS without mesh), every level, with `dec`. */
int st_bc1_decode_set(const st_set *bc1, st_bc1_decoder dec, st_set **out, st_error *e);

/* ---- DDS (dds.c) -----------------------------------------------------------------------
 * Files: "DDS " + DDS_HEADER (124 bytes), FourCC DXT1, every mip level (linear size = the
 * level-0 block bytes). One-face set -> a 2D texture; a cube set -> a DDS cube map (faces
 * +X,-X,+Y,-Y,+Z,-Z, each with its mips); a per-face set whose faces all have one size -> a
 * DX10 texture array (BC1_UNORM or BC1_UNORM_SRGB), followed by a seamtex trailer holding the
 * face adjacency (readers that do not know it ignore trailing bytes); a per-face set whose
 * faces differ in size as a plain DXT1 texture of face 0 followed by seamtex's face table and
 * the other faces (other readers show face 0). A constant face is written as uniform blocks.
 * A seamtex set record after the image data (dds.c) keeps constant faces exact, the colour
 * space, border modes, alpha channel, st_bc1_ext and the metadata (except the importer's
 * "seamtex:source_format", so that a .dds written, imported and written again is the same
 * bytes), so that every set st_bc1_compress_set makes reads back identical. Reading accepts DXT1 (legacy header) and
 * DX10 BC1 (71, 72), 2D, arrays and cubes; sizes from the file are checked against the file
 * length and the caps before anything is allocated; max_bytes caps the arena
 * (0 = ST_DEFAULT_MAX_BYTES). st_dds_write_file writes path.tmp, fsyncs it and renames it. */
int st_dds_write_mem(const st_set *bc1set, uint8_t **buf, size_t *len, st_error *e);
int st_dds_write_file(const st_set *bc1set, const char *path, st_error *e);
int st_dds_read_mem(const uint8_t *buf, size_t len, size_t max_bytes, st_set **out,
                    st_error *e);
int st_dds_read_file(const char *path, size_t max_bytes, st_set **out, st_error *e);

#endif
