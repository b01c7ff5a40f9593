/* tests/common/ptexref.c - one line of a Ptex reference file (see ptexref.h). */
#include "ptexref.h"

#include <stdio.h>
#include <string.h>

const char *const st_ptexref_filters[8] = {"point", "bilinear", "box", "gaussian", "bicubic",
                                           "bspline", "catmullrom", "mitchell"};

int st_refline_parse(const char *line, st_refline *r)
{
    memset(r, 0, sizeof *r);
    const char *p = line + strspn(line, " \t\r\n");
    if (!*p || *p == '#')
        return 0;
    char fn[32];
    int c = sscanf(p, "%u %f %f %f %f %f %f %31s -> %f %f %f %f", &r->face, &r->u, &r->v,
                   &r->dudx, &r->dvdx, &r->dudy, &r->dvdy, fn, &r->ref[0], &r->ref[1],
                   &r->ref[2], &r->ref[3]);
    if (c < 8)
        return -1;
    r->filter = -1;
    for (int i = 0; i < 8; i++)
        if (!strcmp(fn, st_ptexref_filters[i]))
            r->filter = i;
    if (r->filter < 0)
        return -1;
    r->nref = c - 8;
    return 1;
}
