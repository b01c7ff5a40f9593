/* tests/common/atlas_fixture.h - a small atlas mesh made in memory, for the tests of atlas sets
 * that need no shared data.
 *
 * Owns: a unit quad folded at its diagonal whose two triangles lie in two UV charts (one seam
 * between them). Does not own: the mesh type (store/mesh/mesh.h), the image or the atlas
 * import (store/kinds/atlas.h): each test picks its own image.
 */
#ifndef ST_ATLAS_FIXTURE_H
#define ST_ATLAS_FIXTURE_H

#include "mesh.h"

/* The folded quad: 4 positions, 6 UVs, 2 triangles (face 0 and face 1), triangle 0 in UV
 * [0.05, 0.45]^2, triangle 1 in [0.55, 0.95]^2. The caller owns it (st_mesh_free, or hand it to
 * st_atlas_from_image); NULL when out of memory. */
st_mesh *st_fixture_folded_quad(void);

#endif
