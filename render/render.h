/* render/render.h - seamtex-render's renderer: a CPU rasteriser that shades through the texture
 * service, the way a GPU shades through its texture unit.
 *
 * Owns: the types shared by the renderer's files: the mesh it draws (rmesh.c), the camera
 * orbit (camera.c), the MSAA rasteriser and resolve (raster.c), the sampler interface with its
 * two backends (sampler_net.c over libseamtex, sampler_inproc.c over the store), one frame end
 * to end (frame.c), the supersampled reference (reference.c), images (image.c, image_out.c),
 * the Toth 2013 study (study*.c). Does not own: sampling (the daemon or store/sample), the wire
 * (libseamtex), the PNG encoder (OpenImageIO behind store/import's st_image_write).
 *
 * Layering (ARCHITECTURE.md, render/module.mk): every render/ file sees render/, client/,
 * protocol/ and util/ headers only, like any libseamtex client; sampler_inproc.c (the
 * in-process baseline, --inproc) and image_out.c (PNG through OpenImageIO) also see the store,
 * on purpose, as seamtex-bench's in-process baseline does.
 *
 * Errors: functions return 0 or -1 and write a message into a caller's buffer (msg, ml).
 * Ownership: every *_load / *_new returns an object the caller frees with the matching
 * *_free (NULL accepted). No globals: state lives in the structs passed in.
 */
#ifndef RENDER_H
#define RENDER_H

#include <stddef.h>
#include <stdint.h>

#include "seamtex.h"

/* ---- mesh (rmesh.c) ----------------------------------------------------------------------- */

/* Triangles ready to draw. A Ptex mesh (OBJ quads, in the order of the set's faces) gives two
 * triangles per quad, (0,1,2) and (0,2,3), with the face corners' uv (0,0) (1,0) (1,1) (0,1)
 * and the quad's index as face. An atlas mesh (OBJ with vt) is fan-triangulated with face 0
 * and uv = (vt.u, 1 - vt.v): the atlas set's texture space (v down, store/mesh/mesh.h). */
typedef struct rm_mesh {
    uint32_t  nverts, ntris, nfaces;
    float    *pos;      /* nverts * 3 */
    float    *nrm;      /* nverts * 3, area-weighted average of the faces around the vertex */
    uint32_t *tri;      /* ntris * 3 vertex indices */
    float    *uv;       /* ntris * 6: u, v per corner */
    uint32_t *face;     /* ntris: the texture face */
    float     bmin[3], bmax[3];
    int       atlas;
} rm_mesh;

enum { RM_PTEX = 0, RM_ATLAS = 1 };
/* Reads an OBJ file (v, vt, f; other lines ignored). kind RM_PTEX needs every face to be a quad;
 * RM_ATLAS needs a vt on every corner. Caps: 2^24 vertices and faces, finite coordinates. */
rm_mesh *rm_load_obj(const char *path, int kind, char *msg, size_t ml);
/* A mesh made from arrays (tests, generated cubes): quads as in RM_PTEX. Copies the arrays. */
rm_mesh *rm_from_quads(const float *pos, uint32_t nverts, const uint32_t *quads, uint32_t nquads,
                       char *msg, size_t ml);
void rm_free(rm_mesh *m);

/* ---- camera (camera.c) -------------------------------------------------------------------- */

typedef struct rc_camera {
    double eye[3];
    double right[3], up[3], fwd[3];   /* orthonormal; fwd points into the scene */
    double focal;                     /* 1 / tan(fov / 2) */
    double aspect;                    /* width / height */
    double znear;
} rc_camera;

typedef struct rc_orbit {
    unsigned frames;                  /* N frames per turn */
    double   elev_deg;                /* elevation above the bounding box's centre */
    double   dist;                    /* distance in bounding-sphere radii (fits the view at 1) */
    double   fov_deg;                 /* vertical field of view */
    double   azim0_deg;               /* azimuth of frame 0 */
} rc_orbit;

/* Frame i of the orbit around the mesh's bounding box, for a width x height image. */
void rc_orbit_camera(const rc_orbit *o, const rm_mesh *m, unsigned i, unsigned width,
                     unsigned height, rc_camera *cam);

/* ---- sampler interface -------------------------------------------------------------------- */

typedef struct rs_stats {
    uint64_t queries, batches, bytes_out, bytes_in;
    uint64_t refused;                 /* queries whose values came back NaN (a status other
                                         than OK: BAD_FOOTPRINT, NONFINITE, BAD_FACE; or NaN
                                         texels): drawn magenta by rf_render */
    uint64_t zero_coverage;           /* queries answered by the zero rule (coverage 0) */
    uint64_t shm_batches;             /* batches whose queries and reply went through the
                                         shared-memory region (rs_net_shm) */
} rs_stats;

typedef struct rs_sampler rs_sampler;
struct rs_sampler {
    /* Samples n queries with o into out (n * 4 floats: RGBA, channels beyond the set's nchan
     * filled as grey / alpha 1) and cov (n floats, may be NULL); adds to st. 0 or -1 + msg. */
    int  (*sample)(rs_sampler *s, const stc_sample_opts *o, const stc_query *q, size_t n,
                   float *out, float *cov, rs_stats *st, char *msg, size_t ml);
    void (*free)(rs_sampler *s);
    unsigned nchan, kind, nfaces;     /* of the set (kind: 0 per-face, 2 atlas, 3 BC1) */
};
void rs_free(rs_sampler *s);
/* Expands nchan-channel values to RGBA (1: grey, 2: grey + alpha, 3: alpha 1). */
void rs_expand_rgba(const float *in, unsigned nchan, size_t n, float *out);

/* Over a connection the caller owns (sampler_net.c): batches of `batch` queries, up to
 * `inflight` SAMPLE requests outstanding. The set must exist on the daemon. */
rs_sampler *rs_net_new(stc_conn *c, const char *set, unsigned batch, unsigned inflight,
                       char *msg, size_t ml);
/* Shared-memory sampling (PROTOCOL.md 4.12) for the rs_net samplers of c, connected to host:
 * attaches a region that holds `inflight` requests of `batch` queries in outfmt (clamped as
 * rs_net_new clamps them); libseamtex then sends every batch that fits through it, bit for bit
 * the same results. Call once, right after connecting. policy RS_SHM_OFF: nothing; RS_SHM_AUTO:
 * attached when host is unix: and the daemon allows it, else the socket, with the reason in
 * note (nl bytes; "" when off); RS_SHM_ON: as auto, but no region is an error. Returns 1
 * attached (note says the size), 0 the socket, -1 with msg (RS_SHM_ON without a region, or
 * the connection broke). */
enum { RS_SHM_OFF = 0, RS_SHM_AUTO = 1, RS_SHM_ON = 2 };
int rs_net_shm(stc_conn *c, const char *host, int policy, unsigned batch, unsigned inflight,
               unsigned outfmt, char *note, size_t nl, char *msg, size_t ml);
/* In-process (sampler_inproc.c): imports the texture file as the daemon would; for an atlas
 * mesh, texture_path is the OBJ and image its texture image (else NULL). */
rs_sampler *rs_inproc_new(const char *texture_path, const char *image, char *msg, size_t ml);

/* ---- rasteriser (raster.c) ---------------------------------------------------------------- */

#define RR_MAX_MSAA 8
/* The D3D standard sample positions for 1, 2, 4, 8 samples, in 1/16 pixel from the centre.
 * Returns the count, or 0 for another rate. */
unsigned rr_pattern(unsigned msaa, const int8_t **xy);

/* One fragment: a (pixel, triangle) pair with at least one visible sample. */
typedef struct rr_frag {
    uint32_t pixel;                   /* y * width + x */
    uint8_t  mask;                    /* visible samples */
    uint8_t  centroid;                /* 1 when the centre was outside (centroid used) */
    float    light;                   /* shading term at the shading point */
} rr_frag;

typedef struct rr_target {
    unsigned width, height, msaa, nsamp;
    float   *depth;                   /* width * height * nsamp: 1/w, 0 = empty */
    uint32_t *owner;                  /* triangle per sample, UINT32_MAX = background */
    rr_frag *frags;                   /* nfrag fragments, queries[i] belongs to frags[i] */
    stc_query *queries;
    size_t   nfrag, cap;
    uint64_t helper_lanes;            /* 2x2-quad lanes evaluated only for derivatives */
    uint64_t clamped_derivs;          /* fragments whose derivatives were scaled down to
                                         RR_MAX_DERIV (a lane past the plane's horizon) */
} rr_target;

/* The largest derivative (texture units per pixel) a query carries: a helper lane extrapolated
 * past a plane's horizon gives ~1e26 and more, over the sampler's 1e4 (BAD_FOOTPRINT); the four
 * derivatives are then scaled together to this bound (a power of two under 1e4; the largest
 * other one on the study's teapot orbit is 1856, a silhouette), far beyond any face's
 * coarsest level: the lookup is the coarsest level's, as with a GPU's clamped LOD. */
#define RR_MAX_DERIV 8192.0

int  rr_target_init(rr_target *t, unsigned width, unsigned height, unsigned msaa, char *msg,
                    size_t ml);
void rr_target_free(rr_target *t);

/* Rasterises every triangle of m seen by cam: the depth pass (per-sample nearest triangle),
 * then fragments with their queries (shading point at the pixel centre or, when the centre is
 * outside the triangle, the centroid of its covered samples; derivatives from 2x2 pixel quads
 * with helper lanes). 0 or -1 (out of memory). */
int rr_rasterise(rr_target *t, const rm_mesh *m, const rc_camera *cam, char *msg, size_t ml);

/* Box resolve into rgb (width * height * 3 floats, linear): each fragment's colour
 * (frag_rgba[i], 4 floats, times its light term) on its visible samples, bg elsewhere. */
void rr_resolve(const rr_target *t, const float *frag_rgba, const float bg[3], float *rgb);

/* Screen-space projection used by the rasteriser (exposed for tests): x, y in pixels (y down),
 * iw = 1 / view depth. Returns 0 when the point is behind the near plane. */
int rr_project(const rc_camera *cam, unsigned width, unsigned height, const float p[3],
               double *x, double *y, double *iw);

/* ---- one frame (frame.c) ------------------------------------------------------------------ */

typedef struct rf_opts {
    unsigned width, height, msaa;
    unsigned mode;                    /* 0 discard, 1 traverse, 2 clamp */
    unsigned filter, max_aniso;       /* default aniso (3), 16 */
    unsigned outfmt;                  /* STC_OUT_* */
    int      unlit;                   /* 1: texture colour only (no light term) */
    float    bg[3];
} rf_opts;

typedef struct rf_times {
    double raster_ms, sample_ms, shade_ms, total_ms;
} rf_times;

/* Renders one frame: rasterise, sample every fragment through s, resolve. rgb receives
 * width * height * 3 floats. t (may be NULL) keeps the rasteriser's buffers between frames of
 * the same size and rate (pass a zeroed one first; free with rr_target_free). */
int rf_render(const rm_mesh *m, const rc_camera *cam, const rf_opts *o, rs_sampler *s,
              rr_target *t, float *rgb, rf_times *tm, rs_stats *st, char *msg, size_t ml);

/* The reference (reference.c): the frame at ss x ss the resolution, 1 sample per pixel, with
 * o's mode (the study uses Traverse), downsampled with the Mitchell-Netravali filter
 * B = C = 1/3 (radius 2 output pixels). */
int rf_reference(const rm_mesh *m, const rc_camera *cam, const rf_opts *o, unsigned ss,
                 rs_sampler *s, float *rgb, rs_stats *st, char *msg, size_t ml);
/* The filter itself, separable, from (w*ss) x (h*ss) to w x h, 3 channels (exposed for tests). */
int rf_mitchell_down(const float *hi, unsigned w, unsigned h, unsigned ss, float *out);
double rf_mitchell(double x);

/* ---- images (image.c, image_out.c) -------------------------------------------------------- */

/* Writes w x h linear RGB floats as an 8-bit PNG (values clamped to 0..1, written as they
 * are: the renderer treats texel values as the display's values). */
int ri_write_png(const char *path, const float *rgb, unsigned w, unsigned h, char *msg,
                 size_t ml);
/* Copies the (x0, y0, cw, ch) window of a w-wide image, each pixel as a zoom x zoom block,
 * into out (cw*zoom x ch*zoom x 3), clipping to the image (outside: black). */
void ri_crop_zoom(const float *rgb, unsigned w, unsigned h, int x0, int y0, unsigned cw,
                  unsigned ch, unsigned zoom, float *out);
/* Pastes a tw x th image into a w-wide canvas at (x, y). */
void ri_paste(float *canvas, unsigned w, unsigned h, const float *tile, unsigned tw, unsigned th,
              unsigned x, unsigned y);
/* The linear-RGB 2-norm of the difference of pixel i of a and b. */
double ri_pixel_dist(const float *a, const float *b, size_t i);

/* ---- common.c ----------------------------------------------------------------------------- */
double rt_now_ms(void);
/* Formats into msg (ml bytes; NULL / 0 accepted). */
void rt_say(char *msg, size_t ml, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

#endif
