/* store/service/defaultset.c - the built-in "default" set: see defaultset.h for the recipe. */
#include "defaultset.h"

#include <math.h>

#include "ptexfilter.h"
#include "quadmesh.h"

void st_default_set_color(const float P[3], float rgba[4])
{
    float x = P[0], y = P[1], z = P[2];
    float stripe = 0.5f + 0.5f * sinf(18.0f * (x + 0.7f * y - 0.4f * z));
    float base[3] = {
        0.5f + 0.3f * sinf(2.1f * x + 1.3f * y + 0.4f),
        0.5f + 0.3f * sinf(1.7f * y - 2.3f * z + 1.1f),
        0.5f + 0.3f * sinf(2.9f * z + 0.8f * x + 2.0f),
    };
    for (int c = 0; c < 3; c++)
        rgba[c] = base[c] * (0.7f + 0.3f * stripe);
    rgba[3] = 1.0f;
}

static void bake(void *user, uint32_t face, float u, float v, const float P[3], float *out)
{
    (void)user;
    (void)face;
    (void)u;
    (void)v;
    st_default_set_color(P, out);
}

int st_default_set(st_set **out, st_error *e)
{
    *out = NULL;
    st_quadmesh m;
    int rc = st_quadmesh_cube(ST_DEFAULT_SET_N, ST_DEFAULT_SET_SEED, &m, e);
    if (rc != ST_OK)
        return rc;
    st_quad_res_range range = {.seed = ST_DEFAULT_SET_SEED, .lo = 4, .hi = 6};
    st_quadmesh_opts o = {.nchan = 4, .dtype = ST_DT_U8, .has_alpha = 1,
                          .res = st_quad_res_random, .bake = bake, .user = &range};
    rc = st_quadmesh_build(&m, &o, out, e); /* user is the res range; bake ignores it */
    st_quadmesh_free(&m);
    if (rc == ST_OK)
        rc = st_set_meta_add(*out, "seamtex:name", 0, "default", 8, e);
    if (rc == ST_OK) /* so the Ptex filter family can sample it too (ptexfilter.h) */
        rc = st_ptexfilter_prepare(*out, e);
    if (rc != ST_OK) {
        st_set_free(*out);
        *out = NULL;
    }
    return rc;
}
