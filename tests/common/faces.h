/* tests/common/faces.h - face descriptors for the per-face sets tests build by hand.
 *
 * Owns: laying out st_face_desc arrays (sizes, boundaries, joined edges). Does not own: the
 * set (st_set_create), its texels, what a test checks.
 */
#ifndef ST_TEST_FACES_H
#define ST_TEST_FACES_H

#include <stdint.h>

#include "set.h"

/* fd[0..n-1] zeroed, each w x h, every edge a boundary (adjface -1). */
void st_test_faces(st_face_desc *fd, unsigned n, uint32_t w, uint32_t h);

/* Joins edge ea of face a and edge eb of face b: each the other's neighbour there. */
void st_test_join(st_face_desc *fd, int a, int ea, int b, int eb);

#endif
