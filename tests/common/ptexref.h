/* tests/common/ptexref.h - one line of a Ptex reference file (the .txt files of ../shared/data/ptex-ref).
 *
 * Owns: parsing `faceid u v uw1 vw1 uw2 vw2 filter [-> r g b a]` (the query Ptex's
 * PtexFilter::eval answered, and its outputs when the line carries them) and the order of the
 * eight Ptex filter names. Used by the Ptex reference tests and by bench_ptex's query-file
 * mode; and the per-filter tally of a reference file sampled through the store's sampler
 * (st_reftally_*), shared by the quad and the triangle reference tests. Does not own: what a
 * caller samples with it over the wire.
 */
#ifndef ST_TEST_PTEXREF_H
#define ST_TEST_PTEXREF_H

#include <stdint.h>

#include "sample.h"

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

/* Per Ptex filter: queries, queries within tolerance on every channel, largest difference. */
typedef struct st_reftally {
    int   total[8], ok[8];
    float maxd[8];
    int   crossing;   /* lines whose Discard answer differs: the kernel reads a neighbour */
} st_reftally;

/* Samples s (Traverse, through st_sample_batch) at every query line with reference values of
 * the reference file at path, each with its line's filter, and tallies into *t (zeroed
 * first). Tolerance: half an 8-bit step for u8 data, 1e-4 otherwise. verbose: lines that miss
 * are printed. Returns 0, or -1 when the file cannot be read, a line is malformed or the
 * sampler fails. */
int st_reftally_run(const st_set *s, const char *path, int verbose, st_reftally *t);

/* Prints the column header of st_reftally_print's rows. */
void st_reftally_header(void);

/* Prints one row per filter that was queried (base, filter, queries, match%, max|diff|) and
 * returns how many of those match on fewer than 99.9% of their queries. */
int st_reftally_print(const st_reftally *t, const char *base);

#endif
