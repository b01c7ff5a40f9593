/* tests/common/atlas_fixture.c - see atlas_fixture.h. */
#include "atlas_fixture.h"

#include <string.h>

st_mesh *st_fixture_folded_quad(void)
{
    st_mesh *m = NULL;
    st_error e;
    if (st_mesh_alloc(4, 6, 2, &m, &e) != 0)
        return NULL;
    static const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    static const float uv[12] = {0.05f, 0.05f, 0.45f, 0.05f, 0.45f, 0.45f,
                                 0.55f, 0.55f, 0.95f, 0.95f, 0.55f, 0.95f};
    static const uint32_t tp[6] = {0, 1, 2, 0, 2, 3}, tu[6] = {0, 1, 2, 3, 4, 5};
    memcpy(m->pos, pos, sizeof pos);
    memcpy(m->uv, uv, sizeof uv);
    memcpy(m->tri_pos, tp, sizeof tp);
    memcpy(m->tri_uv, tu, sizeof tu);
    m->tri_face[1] = 1;
    return m;
}
