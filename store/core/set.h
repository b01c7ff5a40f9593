/* store/core/set.h - texture sets held in memory: per-face textures with mip chains and Ptex
 * adjacency, cube maps (6-face sets) and atlas textures (one face plus a mesh in `ext`).
 *
 * Owns: the in-memory layout of a set, its creation and validation, mip generation, metadata.
 * Does not own: files (ptex*.c, import*.c), sampling (sample*.c), sockets (never).
 *
 * Layout, chosen for sampling speed (numbers in ARCHITECTURE.md):
 *   - one st_face record of 64 bytes per face, in one array;
 *   - one uint64_t offset per (face, level) in one array (`level_off`), face f's levels start
 *     at level_off[faces[f].lvl];
 *   - every texel of every level of every face in ONE allocation (`texels`), texels
 *     interleaved by channel, rows of u (u varies fastest), level 0 first, then each box
 *     reduction, per axis down to 1 texel: level L is max(1, w>>L) x max(1, h>>L).
 *   - a constant face stores exactly one texel, shared by all of its levels.
 *
 * Conventions (Ptex): edges 0 bottom (v=0), 1 right (u=1), 2 top (v=1), 3 left (u=0);
 * corner c is where edge c starts: 0 (0,0), 1 (1,0), 2 (1,1), 3 (0,1). adjface[e] is the
 * neighbour across edge e (-1 on a boundary) and adjedge[e] is that edge's id in the
 * neighbour. Faces are oriented consistently, so a shared edge runs in opposite directions in
 * its two faces.
 *
 * Ownership: st_set_create returns a set the caller owns and frees with st_set_free (NULL is
 * accepted). A set is immutable once published: many threads may sample it at once.
 */
#ifndef ST_SET_H
#define ST_SET_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"
#include "half.h"

#define ST_MAX_LOG2      15
#define ST_MAX_DIM       (1u << ST_MAX_LOG2)   /* per face and axis, 32768 */
#define ST_MAX_CHANNELS  4
#define ST_MAX_LEVELS    16
#define ST_MAX_FACES     (1u << 26)
#define ST_DEFAULT_MAX_BYTES ((size_t)8 << 30)  /* cap on one set's texel arena */

typedef enum st_dtype {          /* numbering is Ptex's DataType */
    ST_DT_U8   = 0,
    ST_DT_U16  = 1,
    ST_DT_HALF = 2,
    ST_DT_F32  = 3
} st_dtype;

typedef enum st_kind {
    ST_KIND_PERFACE = 0,         /* Ptex-style quad faces */
    ST_KIND_CUBE    = 1,         /* 6 faces, fixed adjacency, see cube.h */
    ST_KIND_ATLAS   = 2,         /* face 0 is the atlas image; mesh and seams in ext */
    ST_KIND_BC1     = 3          /* levels hold BC1 blocks (8 bytes per 4x4 texels, row-major
                                    blocks, ceil(w/4) x ceil(h/4)); dtype u8, 4 channels as
                                    decoded; a constant face holds one texel of 4 bytes */
} st_kind;

typedef enum st_colorspace { ST_CS_LINEAR = 0, ST_CS_SRGB = 1 } st_colorspace;

enum st_face_flags {
    ST_FACE_CONSTANT = 1,        /* one texel for the whole face */
    ST_FACE_SUBFACE  = 2         /* a Ptex subface of a non-quad face */
};

enum { ST_EDGE_BOTTOM = 0, ST_EDGE_RIGHT = 1, ST_EDGE_TOP = 2, ST_EDGE_LEFT = 3 };

/* valence[c] bit: the vertex at corner c lies on a boundary (its count is then partial) */
#define ST_VALENCE_BOUNDARY 0x80u

/* What a creator supplies for each face. */
typedef struct st_face_desc {
    uint32_t w, h;               /* level-0 size in texels, 1..ST_MAX_DIM */
    uint8_t  flags;              /* st_face_flags */
    int32_t  adjface[4];         /* neighbour across edge e, -1 = boundary */
    int8_t   adjedge[4];         /* edge id in that neighbour, 0..3 (ignored when -1) */
} st_face_desc;

/* One face as stored: 64 bytes, everything the sampler needs without chasing pointers. */
typedef struct st_face {
    uint32_t w, h;               /* level-0 size */
    uint8_t  ulog2, vlog2;       /* floor(log2(w)), floor(log2(h)) */
    uint8_t  nlevels;            /* levels stored: floor(log2(max(w,h))) + 1 */
    uint8_t  flags;              /* st_face_flags */
    uint32_t lvl;                /* index of level 0 in set->level_off */
    int32_t  adjface[4];
    uint8_t  adjedge[4];
    int32_t  cornerface[4];      /* diagonal face at a regular (valence 4, interior) vertex,
                                    else -1 */
    uint8_t  cornercorner[4];    /* the corner of cornerface[c] that lies on this vertex */
    uint8_t  valence[4];         /* faces around the vertex at corner c (| BOUNDARY) */
    uint32_t reserved;
} st_face;

typedef struct st_set_info {
    uint32_t nfaces;
    uint8_t  nchan;              /* 1..4 */
    uint8_t  dtype;              /* st_dtype */
    int8_t   alpha_chan;         /* -1 = none */
    uint8_t  kind;               /* st_kind */
    uint8_t  colorspace;         /* st_colorspace */
    uint8_t  premultiplied;      /* colour channels are premultiplied by alpha */
    uint8_t  border_u, border_v; /* Ptex border modes: 0 clamp, 1 black, 2 periodic */
    uint8_t  meshtype;           /* st_meshtype: 0 quad, 1 triangle (NOT Ptex's numbering,
                                    where 0 is triangle) */
    uint8_t  edgefilter;         /* st_edgefilter: Ptex's edge filter mode, 0 none, 1 tanvec
                                    (channels 0-1 a tangent-space vector, rotated across
                                    rotated edges by the quad Ptex filters' Traverse) */
} st_set_info;

/* Ptex's edge filter mode (its numbering). */
typedef enum st_edgefilter { ST_EDGEFILTER_NONE = 0, ST_EDGEFILTER_TANVEC = 1 } st_edgefilter;

/* Mesh type of a per-face set. A triangle face (Ptex meshtype triangle) is square (w == h),
 * never a subface, has three edges - 0 (v = 0), 1 (u + v = 1), 2 (u = 0), corner c where edge
 * c starts: 0 (0,0), 1 (1,0), 2 (0,1) - so adjface[3] is -1 and adjedge[] is 0..2; each
 * level holds Ptex's packed triangle layout (docs/ptex.md, "Triangle meshes"). */
typedef enum st_meshtype { ST_MESH_QUAD = 0, ST_MESH_TRIANGLE = 1 } st_meshtype;

/* Metadata key (string "srgb") that records an sRGB set in files without a colour space of
 * their own (Ptex): written by exporters, honoured by the importer. */
#define ST_META_COLORSPACE "seamtex:colorspace"

/* Metadata entry, Ptex-typed: 0 string, 1 int8, 2 int16, 3 int32, 4 float, 5 double. */
typedef struct st_meta_entry {
    char    *key;
    uint8_t  type;
    uint32_t count;              /* elements (string: bytes including the NUL) */
    void    *data;
} st_meta_entry;

/* What set->ext holds: at most one extension per set, tagged with its kind, owned by the set
 * and freed with it. Readers ask for a kind (st_set_ext_get) and get NULL for any other, so no
 * module mistakes another module's data for its own. */
typedef enum st_ext_kind {
    ST_EXT_NONE    = 0,
    ST_EXT_ATLAS   = 1,          /* st_atlas (kinds/atlas.h): mesh and chart mask of an atlas */
    ST_EXT_BC1     = 2,          /* st_bc1_ext (core/bc1_texel.h): what a BC1 set keeps of its
                                    source */
    ST_EXT_PTEXRES = 3           /* st_ptexres (ptex/ptexres.h): every Ptex resolution of every
                                    face, read by the Ptex filter family */
} st_ext_kind;

struct st_set;
struct st_sample_opts;
struct st_query;
struct st_chart_ids;

/* A filter family that an extension's module provides (the Ptex filters, ptex/): the sampler
 * (sample/) calls it for the filter ids it does not implement itself, so the sampler never
 * depends on that module. Same contract as st_sample_batch (sample/sample.h). */
typedef int (*st_ext_filter_fn)(const struct st_set *s, const struct st_sample_opts *o,
                                const struct st_query *q, size_t n, float *out,
                                float *coverage, uint8_t *status);

/* Makes the set's levels past level 0 when an extension's module deferred them (the Ptex
 * reader: st_set_levels below). Thread-safe; once they are made, one atomic load. */
typedef int (*st_ext_levels_fn)(const struct st_set *s, st_error *e);

typedef struct st_set_ext {
    uint8_t          kind;       /* st_ext_kind; ST_EXT_NONE: every other field is NULL */
    void            *data;       /* owned by the set */
    void           (*free)(void *data);          /* NULL: nothing to free */
    size_t         (*memory)(const void *data);  /* bytes data holds (NULL: 0) */
    st_ext_filter_fn filter;     /* NULL: this extension adds no filters */
    st_ext_levels_fn levels;     /* NULL: every level is made (see st_set_levels) */
    const struct st_chart_ids *charts; /* an atlas's chart id per texel of every level, which
                                    Discard reads (sample/sample.h); NULL or nlevels 0: none */
    /* With charts: builds them when they are not (an atlas opened from a native file builds
     * them on its first chart-mode sample) and pins them until charts_unpin, so that no
     * memory-budget drop frees them meanwhile; the sampler calls it once per chart-mode batch
     * before reading charts. ST_OK (pinned) or an ST_E* code (nothing pinned). NULL: charts
     * is always built. */
    int            (*charts_pin)(const struct st_set *s, st_error *e);
    void           (*charts_unpin)(const struct st_set *s);
} st_set_ext;

typedef struct st_set {
    st_set_info    info;
    st_face       *faces;        /* info.nfaces records */
    uint64_t      *level_off;    /* byte offsets into texels, see layout above */
    uint8_t       *texels;       /* the arena */
    size_t         texel_bytes;  /* size of the arena */
    st_meta_entry *meta;         /* nmeta entries, owned */
    uint32_t       nmeta;
    st_set_ext     ext;          /* kind-specific data owned by the set, tagged */
    /* A set opened from a native file (store/native/native.h) samples straight from a
     * read-only shared mapping of it: faces, level_off and texels then point INTO map and
     * are never written nor freed; st_set_free munmaps map and closes map_fd. NULL map: the
     * three arrays are heap allocations owned by the set. */
    void          *map;          /* start of the mapping, NULL for a heap set */
    size_t         map_len;      /* bytes mapped */
    int            map_fd;       /* the file, kept open for posix_fadvise (valid when map) */
    uint64_t       last_use_ms;  /* atomic: last sample (monotonic ms), for the memory budget */
    uint32_t       cold;         /* atomic: 1 once the budget released it, until sampled */
    uint64_t       res_bytes;    /* atomic: the budget's last resident figure of the mapping */
    uint64_t       res_ms;       /* atomic: when it was taken (monotonic ms), 0 = never */
} st_set;

/* Bytes per channel of a dtype (1, 2, 2, 4); 0 for an invalid dtype. */
static inline size_t st_dtype_size(unsigned dtype)
{
    return dtype == ST_DT_U8 ? 1 : dtype == ST_DT_U16 || dtype == ST_DT_HALF ? 2
                                 : dtype == ST_DT_F32 ? 4 : 0;
}
static inline size_t st_texel_size(const st_set *s)
{
    return st_dtype_size(s->info.dtype) * s->info.nchan;
}
static inline uint32_t st_level_w(const st_face *f, unsigned level)
{
    uint32_t w = f->w >> level;
    return w ? w : 1;
}
static inline uint32_t st_level_h(const st_face *f, unsigned level)
{
    uint32_t h = f->h >> level;
    return h ? h : 1;
}
/* Pointer to level `level` (< nlevels) of face f: st_level_w x st_level_h texels, or one
 * texel for a constant face. Levels >= 1 of a set from the Ptex reader hold nothing defined
 * until st_set_levels(s) has returned ST_OK (level 0 always does). */
static inline uint8_t *st_face_level(const st_set *s, uint32_t f, unsigned level)
{
    return s->texels + s->level_off[s->faces[f].lvl + level];
}

/* Channel value of a texel as float: u8 /255, u16 /65535, half, float. */
static inline float st_channel_get(unsigned dtype, const void *p, unsigned c)
{
    switch (dtype) {
    case ST_DT_U8:   return ((const uint8_t *)p)[c] * (1.0f / 255.0f);
    case ST_DT_U16:  return ((const uint16_t *)p)[c] * (1.0f / 65535.0f);
    case ST_DT_HALF: return st_half_to_float(((const uint16_t *)p)[c]);
    default:         return ((const float *)p)[c];
    }
}
/* Stores v into channel c with rounding and clamping for the integer types. */
static inline void st_channel_put(unsigned dtype, void *p, unsigned c, float v)
{
    switch (dtype) {
    case ST_DT_U8: {
        float x = v * 255.0f + 0.5f;
        ((uint8_t *)p)[c] = (uint8_t)(x <= 0.0f || x != x ? 0 : x >= 255.0f ? 255 : (int)x);
        break;
    }
    case ST_DT_U16: {
        float x = v * 65535.0f + 0.5f;
        ((uint16_t *)p)[c] = (uint16_t)(x <= 0.0f || x != x ? 0 : x >= 65535.0f ? 65535 : (int)x);
        break;
    }
    case ST_DT_HALF: ((uint16_t *)p)[c] = st_float_to_half(v); break;
    default:         ((float *)p)[c] = v; break;
    }
}

/* Creates a set with zeroed texels. Validates everything from outside first: channel count,
 * dtype, face count, sizes, adjacency (in range, edge ids 0..3, symmetric between faces of
 * the same kind; a subface <-> main face link may be one-sided, as Ptex writes them), and
 * the total arena size against max_bytes (0 = ST_DEFAULT_MAX_BYTES). Computes valences and
 * diagonal (corner) faces. The error names the face and edge at fault. */
int st_set_create(const st_set_info *info, const st_face_desc *faces, size_t max_bytes,
                  st_set **out, st_error *e);

/* The same, but the texels are left as the allocator returned them (the slack after the last
 * one is zeroed): for a reader that writes every byte of every level itself before the set
 * is used or freed (the Ptex reader), so that the arena is written once instead of zeroed
 * first. A reader that fails half way frees the set unread. */
int st_set_create_unzeroed(const st_set_info *info, const st_face_desc *faces, size_t max_bytes,
                           st_set **out, st_error *e);

/* Frees the set and everything it owns (unmaps a mapped set); NULL is accepted. */
void st_set_free(st_set *s);

/* Fills levels 1.. of face f (or of every face when f == UINT32_MAX) by 2x2 box reduction of
 * the level above, computed in float and rounded to the dtype (an odd last row or column of
 * a non-power-of-two face is dropped, as a 2x2 box would). Constant faces are left alone. */
void st_set_build_mips(st_set *s, uint32_t f);

/* As st_set_build_mips for one quad face f, with a label per texel of every level (ids[l]:
 * st_level_w x st_level_h labels of level l, row by row; NULL: no labels): a texel of level l
 * labelled d != 0 is the mean of those of its (up to 2 x 2) level l - 1 texels labelled d, so
 * one region's texels never average another's (an atlas's charts: kinds/atlas.c); a texel
 * labelled 0 the mean of all of them. Each label d != 0 of level l must be the label of at
 * least one of its level l - 1 texels (the rule an atlas's chart ids are reduced by); a texel
 * where none is gets the mean of none, 0. Triangle, BC1 and constant faces are left alone. */
void st_set_build_mips_labelled(st_set *s, uint32_t f, const uint16_t *const *ids);

/* Returns 1 when every level-0 texel of face f is bit-identical (importers use it to decide
 * whether to store a face as constant; nothing is changed). */
int st_face_is_uniform(const st_set *s, uint32_t f);

/* Sets one metadata entry (copies key and data): a key already present gets the new type and
 * value in its place (a key holds one value, the last one set, as Ptex reads repeated keys);
 * a new key is appended. */
int st_set_meta_add(st_set *s, const char *key, unsigned type, const void *data,
                    uint32_t count, st_error *e);
/* Finds an entry by key, NULL when absent. */
const st_meta_entry *st_set_meta_find(const st_set *s, const char *key);

/* Bytes the set holds in memory (face table, offsets, texels - an arena of its own as
 * allocated, whole huge pages included (util/bigalloc.h) - metadata and its extension, as
 * the extension's memory callback counts it). */
size_t st_set_memory(const st_set *s);

/* Bytes the set holds on the heap besides its record and texture data: its metadata and its
 * extension (as the extension's memory callback counts it: a built Ptex table, an atlas's
 * mesh, chart mask and built chart data). For a heap set (no mapping) every byte it holds,
 * st_set_memory. What the memory budget counts of a mapped set beside its mapped pages. */
size_t st_set_heap_memory(const st_set *s);

/* The set's extension data when it is of kind k, else NULL. */
static inline void *st_set_ext_get(const st_set *s, st_ext_kind k)
{
    return s && s->ext.kind == (uint8_t)k ? s->ext.data : NULL;
}
/* Makes sure every level of s holds its texels: ST_OK at once (one atomic load) for any set
 * but one whose reader deferred its levels past level 0 (the Ptex reader keeps the stored
 * reductions zipped until first use, ptex.h); for that one, the first call inflates and
 * fills them (any number of threads may call at once; one does the work, the others wait).
 * Every reader of a level >= 1 (samplers, filters, writers, ...) calls it once per call,
 * never per query, and reads no level >= 1 when it fails. A failure is final: ST_EFORMAT
 * with the same message (the level, face and stream at fault) from every later call, or
 * ST_ENOMEM. Level 0, the faces, offsets and metadata never depend on it. */
static inline int st_set_levels(const st_set *s, st_error *e)
{
    return s->ext.levels ? s->ext.levels(s, e) : ST_OK;
}

/* Attaches x to s, freeing the extension s had (x may be NULL: detach and free). Levels that
 * the old extension deferred are made first (st_set_levels; should that fail, the levels past
 * level 0 are zeroed, not left undefined). */
void st_set_ext_attach(st_set *s, const st_set_ext *x);

/* Re-checks adjacency of an existing set (used by importers that patch adjacency). */
int st_set_check_adjacency(const st_set *s, st_error *e);

#endif
