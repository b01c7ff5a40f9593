/* tests/common/faces.c - see faces.h. */
#include "faces.h"

#include <string.h>

void st_test_faces(st_face_desc *fd, unsigned n, uint32_t w, uint32_t h)
{
    memset(fd, 0, n * sizeof *fd);
    for (unsigned f = 0; f < n; f++) {
        fd[f].w = w;
        fd[f].h = h;
        for (int k = 0; k < 4; k++)
            fd[f].adjface[k] = -1;
    }
}

void st_test_join(st_face_desc *fd, int a, int ea, int b, int eb)
{
    fd[a].adjface[ea] = b;
    fd[a].adjedge[ea] = (int8_t)eb;
    fd[b].adjface[eb] = a;
    fd[b].adjedge[eb] = (int8_t)ea;
}
