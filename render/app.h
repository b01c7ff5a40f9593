/* render/app.h - seamtex-render's command line and the jobs it runs: one frame (or an orbit,
 * or a strip) in any mode and rate (main.c), and the Toth 2013 study (study.c).
 *
 * Owns: the configuration struct both read, the sampler set-up they share (app.c: connect,
 * upload the texture, open the daemon and in-process samplers). Does not own: rendering.
 */
#ifndef RENDER_APP_H
#define RENDER_APP_H

#include "render.h"

#define APP_MAX_MESHES 8

typedef struct app_cfg {
    const char *host;
    unsigned    port;                  /* 0: no daemon (only --inproc) */
    const char *set;                   /* set name on the daemon; NULL: from the file name */
    const char *texture;               /* texture file; NULL: MESH.ptx beside the mesh (an atlas
                                          mesh needs its image here) */
    int         no_upload;             /* the set is on the daemon already */
    int         inproc;                /* sample in-process */
    const char *meshes[APP_MAX_MESHES];
    unsigned    nmeshes;
    unsigned    width, height, msaa;
    int         mode;                  /* -1: every mode */
    unsigned    filter, max_aniso, outfmt;
    rc_orbit    orbit;
    unsigned    frame;                 /* which frame of the orbit */
    int         all_frames;            /* every frame of the orbit */
    unsigned    strip;                 /* frames in an animation strip (0: none) */
    unsigned    reference;             /* 0, or the supersampling factor of a reference */
    unsigned    repeat;                /* renders per frame (timing medians) */
    int         breakdown;             /* also time in-process sampling of the same queries */
    unsigned    batch, inflight;
    int         shm;                   /* RS_SHM_AUTO (default), RS_SHM_ON, RS_SHM_OFF */
    const char *out;                   /* output folder */
    const char *toth;                  /* study output folder */
    unsigned    ref_ss;                /* study reference factor (8) */
    unsigned    closeup_size;          /* close-up crop in pixels */
    unsigned    bc1_level;
    int         quiet;
} app_cfg;

/* The file that becomes the mesh's set and the kind of mesh: a --texture .ptx or a .ptx beside
 * the OBJ (Ptex mesh); with a --texture image, the OBJ itself (atlas mesh) with *image = that
 * image. path is a caller's buffer of cap bytes. -1 with a message when neither is there. */
int app_texture_for(const app_cfg *c, const char *mesh, char *path, size_t cap, int *kind,
                    const char **image, char *msg, size_t ml);
/* The set name for a texture file: "render-" + its base name without extension, cleaned to
 * the set-name alphabet. */
void app_set_name(const char *path, const char *prefix, char *name, size_t cap);
/* Connects to the daemon (once per process; *conn NULL first): host:port, or host alone when
 * it is a unix: address; then shared memory by c->shm (rs_net_shm; a unix: daemon that
 * refuses it under auto is noted on stderr and the socket used). */
int app_connect(const app_cfg *c, stc_conn **conn, char *msg, size_t ml);
/* Uploads path as set name (REPLACE), unless c->no_upload; with an image (atlas mesh), the
 * image first as name + "-tex", then the OBJ with the option texture=<that set>. */
int app_upload(const app_cfg *c, stc_conn *conn, const char *path, const char *image,
               const char *name, char *msg, size_t ml);

int study_run(const app_cfg *c);

#endif
