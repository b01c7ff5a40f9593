/* render/frame.c - one frame of seamtex-render end to end: rasterise, sample every fragment's
 * query through the sampler (daemon or in-process) in one call, shade (texture times the light
 * term; a query the sampler refused drawn magenta and counted) and box-resolve.
 *
 * Owns: the order of those steps, their timing, the sampling options a frame uses (Toth's
 * setup: anisotropic filtering, 16 probes; Discard's zero-coverage rule is Listing 1 lines
 * 14-15, zero_rule 1 "clamp"). Does not own: the steps themselves.
 */
#include "render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

void rs_free(rs_sampler *s)
{
    if (s)
        s->free(s);
}

void rs_expand_rgba(const float *in, unsigned nchan, size_t n, float *out)
{
    for (size_t i = 0; i < n; i++) {
        const float *p = in + i * nchan;
        float *o = out + 4 * i;
        switch (nchan) {
        case 1: o[0] = o[1] = o[2] = p[0]; o[3] = 1; break;
        case 2: o[0] = o[1] = o[2] = p[0]; o[3] = p[1]; break;
        case 3: o[0] = p[0]; o[1] = p[1]; o[2] = p[2]; o[3] = 1; break;
        default: o[0] = p[0]; o[1] = p[1]; o[2] = p[2]; o[3] = p[3]; break;
        }
    }
}

int rf_render(const rm_mesh *m, const rc_camera *cam, const rf_opts *o, rs_sampler *s,
              rr_target *t, float *rgb, rf_times *tm, rs_stats *st, char *msg, size_t ml)
{
    rr_target local = { 0 };
    if (!t)
        t = &local;
    if (!t->depth || t->width != o->width || t->height != o->height || t->msaa != o->msaa) {
        rr_target_free(t);
        if (rr_target_init(t, o->width, o->height, o->msaa, msg, ml) != 0)
            return -1;
    }
    int rc = -1;
    float *rgba = NULL;
    double t0 = rt_now_ms();
    if (rr_rasterise(t, m, cam, msg, ml) != 0)
        goto out;
    if (o->unlit)
        for (size_t i = 0; i < t->nfrag; i++)
            t->frags[i].light = 1.0f;
    double t1 = rt_now_ms();
    rgba = malloc((t->nfrag ? t->nfrag : 1) * 4 * sizeof *rgba);
    if (!rgba) {
        snprintf(msg, ml, "out of memory for %zu fragments' colours", t->nfrag);
        goto out;
    }
    stc_sample_opts so = { .mode = o->mode, .filter = o->filter, .zero_rule = 1,
                           .max_aniso = o->max_aniso, .outfmt = o->outfmt };
    if (t->nfrag && s->sample(s, &so, t->queries, t->nfrag, rgba, NULL, st, msg, ml) != 0)
        goto out;
    double t2 = rt_now_ms();
    /* A query the sampler refused comes back NaN (docs/sampler.md "Bad queries"): drawn
     * magenta and counted, never a silent black pixel (NaN would also poison the pixel's other
     * fragments in the resolve). */
    for (size_t i = 0; i < t->nfrag; i++) {
        float *c = rgba + 4 * i;
        if (isnan(c[0]) || isnan(c[1]) || isnan(c[2])) {
            c[0] = 1, c[1] = 0, c[2] = 1, c[3] = 1;
            if (st)
                st->refused++;
        }
    }
    rr_resolve(t, rgba, o->bg, rgb);
    double t3 = rt_now_ms();
    if (tm)
        *tm = (rf_times){ t1 - t0, t2 - t1, t3 - t2, t3 - t0 };
    rc = 0;
out:
    free(rgba);
    if (t == &local)
        rr_target_free(&local);
    return rc;
}
