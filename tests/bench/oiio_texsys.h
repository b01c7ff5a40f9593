/* tests/bench/oiio_texsys.h - the OpenImageIO side of bench_native's out-of-core comparison
 * (oiio_texsys.cpp, a thin C++ shim with extern "C"): writing one image a .tx file is made
 * from, and an in-process OIIO TextureSystem with a memory limit. Bench-only code: seamtex
 * itself never links it.
 *
 * Ownership: bto_create's TextureSystem is freed with bto_free; handles belong to it;
 * bto_thread's per-thread info is freed with bto_thread_free before bto_free.
 */
#ifndef OIIO_TEXSYS_H
#define OIIO_TEXSYS_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Writes a w x h image of nchan channels (dtype as st_dtype: 0 u8, 1 u16, 2 half, 3 float),
 * rows top to bottom, channels interleaved, to path (format from its extension). 0, or -1
 * with a message in err. */
int bto_write_image(const char *path, uint32_t w, uint32_t h, unsigned nchan, unsigned dtype,
                    const void *pixels, char *err, size_t errcap);

typedef struct bto_ts bto_ts;

/* A private (not the shared) TextureSystem with max_memory_MB = max_mb, max_open_files =
 * max_files, deduplicate off (the .tx copies are distinct textures, as seamtex's sets are). */
bto_ts *bto_create(double max_mb, int max_files);
void bto_free(bto_ts *t);
/* An opaque texture handle for a file, NULL when OIIO cannot resolve it. */
void *bto_handle(bto_ts *t, const char *path);
void *bto_thread(bto_ts *t);
void bto_thread_free(bto_ts *t, void *thread);

/* One lookup: texture coordinates and their derivatives (OIIO's s, t: 0..1 over the image). */
typedef struct bto_query {
    float s, t, dsdx, dtdx, dsdy, dtdy;
} bto_query;

/* n lookups on one texture, nchan floats each into out; bilinear within one MIP level
 * (MipModeOneLevel, InterpBilinear), anisotropic 1, clamp wrap. Returns the lookups that
 * failed (0 on success). */
size_t bto_sample(bto_ts *t, void *thread, void *handle, const bto_query *q, size_t n,
                  int nchan, float *out);

/* An ImageCache statistic ("stat:cache_memory_used", "stat:tiles_created",
 * "stat:bytes_read", ...) as an integer; 0 when unknown. */
uint64_t bto_stat(bto_ts *t, const char *name);
/* Appends OIIO's error text (if any) into err. */
void bto_error(bto_ts *t, char *err, size_t errcap);

#ifdef __cplusplus
}
#endif

#endif
