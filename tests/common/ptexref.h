/* tests/common/ptexref.h - one line of a Ptex reference file (the .txt files of ../shared/data/ptex-ref).
 *
 * Owns: parsing `faceid u v uw1 vw1 uw2 vw2 filter [-> r g b a]` (the query Ptex's
 * PtexFilter::eval answered, and its outputs when the line carries them) and the order of the
 * eight Ptex filter names. Used by the Ptex reference tests and by bench_ptex's query-file
 * mode. Does not own: what a caller samples with it (store or wire query types).
 */
#ifndef ST_TEST_PTEXREF_H
#define ST_TEST_PTEXREF_H

#include <stdint.h>

/* The Ptex filter names in the order of ST_FILTER_PTEX_POINT.. (and of the wire's filters
 * 8..15): point, bilinear, box, gaussian, bicubic, bspline, catmullrom, mitchell. */
extern const char *const st_ptexref_filters[8];

typedef struct st_refline {
    uint32_t face;
    float    u, v, dudx, dvdx, dudy, dvdy;
    int      filter;   /* 0..7, index in st_ptexref_filters */
    int      nref;     /* reference values after "->" (0..4) */
    float    ref[4];
} st_refline;

/* 1: a query line parsed into *r; 0: a blank or '#' line; -1: anything else (too few fields
 * or an unknown filter name). */
int st_refline_parse(const char *line, st_refline *r);

#endif
