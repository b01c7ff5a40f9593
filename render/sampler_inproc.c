/* render/sampler_inproc.c - seamtex-render's in-process sampler (--inproc): the texture file is
 * imported with the store's importer, as the daemon imports an upload, and sampled with
 * st_sample_batch, as the daemon's SAMPLE handler does. The baseline the daemon path is
 * compared with; it links the store on purpose (render/module.mk), like seamtex-bench's.
 *
 * Owns: the set it imported (freed with the sampler). Does not own: sampling.
 */
#include "render.h"

#include <stdio.h>
#include <stdlib.h>

#include "import.h"
#include "sample.h"

#define INPROC_CHUNK 4096

typedef struct inproc {
    rs_sampler base;
    st_set *set;
    float *tmp;      /* INPROC_CHUNK * nchan */
} inproc;

static int inproc_sample(rs_sampler *s, const stc_sample_opts *o, const stc_query *q, size_t n,
                         float *out, float *cov, rs_stats *st, char *msg, size_t ml)
{
    inproc *p = (inproc *)s;
    st_sample_opts so = { .mode = (uint8_t)o->mode, .filter = (uint8_t)o->filter,
                          .zero_rule = (uint8_t)o->zero_rule, .max_aniso = (uint8_t)o->max_aniso,
                          .sharpness = o->sharpness, .width = o->width, .blur = o->blur,
                          .lerp = (o->want & STC_WANT_LERP) != 0 };
    st_query sq[INPROC_CHUNK];
    float c[INPROC_CHUNK];
    for (size_t i = 0; i < n; i += INPROC_CHUNK) {
        size_t k = n - i < INPROC_CHUNK ? n - i : INPROC_CHUNK;
        for (size_t j = 0; j < k; j++) {
            const stc_query *a = &q[i + j];
            sq[j] = (st_query){ a->face, a->u, a->v, a->dudx, a->dvdx, a->dudy, a->dvdy };
        }
        int rc = st_sample_batch(p->set, &so, sq, k, p->tmp, c, NULL);
        if (rc < 0) {
            snprintf(msg, ml, "st_sample_batch: %s", st_strerror(rc));
            return -1;
        }
        rs_expand_rgba(p->tmp, s->nchan, k, out + 4 * i);
        for (size_t j = 0; j < k; j++) {
            if (cov)
                cov[i + j] = c[j];
            st->zero_coverage += c[j] == 0;
        }
        st->batches++;
    }
    st->queries += n;
    return 0;
}

static void inproc_free(rs_sampler *s)
{
    inproc *p = (inproc *)s;
    st_set_free(p->set);
    free(p->tmp);
    free(p);
}

rs_sampler *rs_inproc_new(const char *texture_path, const char *image, char *msg, size_t ml)
{
    inproc *p = calloc(1, sizeof *p);
    if (!p) {
        snprintf(msg, ml, "out of memory");
        return NULL;
    }
    st_error e;
    st_error_clear(&e);
    st_import_opts io;
    st_import_opts_init(&io);
    io.texture_path = image;
    if (st_import_file(texture_path, &io, &p->set, &e) != 0) {
        snprintf(msg, ml, "%s: %s", texture_path, e.msg);
        free(p);
        return NULL;
    }
    p->base.sample = inproc_sample;
    p->base.free = inproc_free;
    p->base.nchan = p->set->info.nchan;
    p->base.kind = p->set->info.kind;
    p->base.nfaces = p->set->info.nfaces;
    p->tmp = malloc((size_t)INPROC_CHUNK * p->base.nchan * sizeof *p->tmp);
    if (!p->tmp) {
        snprintf(msg, ml, "out of memory");
        inproc_free(&p->base);
        return NULL;
    }
    return &p->base;
}
