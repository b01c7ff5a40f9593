// ptexq - evaluate a seamtex Ptex reference query file with the Ptex library itself
// (PtexFilter::getFilter + PtexFilter::eval), dump the outputs and time them.
//
// usage: ptexq FILE.ptx QUERIES.txt [--dump OUT] [--values OUT] [--reps N] [--min-ms M]
//              [--whole] [--check] [--sharpness S] [--width W] [--blur B] [--lerp]
//              [--noedgeblend]
//   QUERIES.txt  lines `faceid u v uw1 vw1 uw2 vw2 filter [-> c0 c1 c2 [c3]]` (the format of
//                shared/data/ptex-ref/ref_*.txt; blank and '#' lines skipped)
//   --dump OUT   each query line again, in the reference form: the query text up to the
//                filter name, then ` -> ` and the outputs (%.9g), so `diff OUT REF` compares
//   --values OUT only the outputs, one line per query, %.9g separated by spaces (the form of
//                seamtex's `bench_ptex --queries ... --dump`)
//   --check      compare with the reference values in the file: exact (%.9g text) and within
//                seamtex's tolerance (0.5/255 for u8 data, 1e-4 otherwise)
//   timing       thread CPU time (CLOCK_THREAD_CPUTIME_ID), like bench_ptex. Default grouping
//                = bench_ptex's: per filter, its lines in file order as one batch, repeated
//                for >= --min-ms (default 15), median of --reps (default 3) runs; prints
//                M queries/s per filter and overall (total queries / sum of per-filter
//                times). --whole: the whole list in file order as one batch instead.
//   --reps 0     no timing (dump / check only)
//   --sharpness S  PtexFilter::Options::sharpness (the `bicubic` filter only; default 0: the
//                  B-spline); --lerp  Options::lerp = true (default false)
//   --noedgeblend  Options::noedgeblend = true (default false): no neighbour is read, the
//                  kernel merged at every edge by the border mode (compare with seamtex's
//                  Clamp: bench_ptex --modes clamp)
//   --width W      eval's width (default 1; 0 is read as 1, as seamtex reads it)
//   --blur B       eval's blur (default 0)
//                these apply to every query of the run (the same meaning as bench_ptex's
//                options of the same names)
// Default filter options = the reference generator's: width=1, blur=0, lerp=false,
// sharpness=0, noedgeblend=false, no premultiplication; the texture is opened with
// PtexTexture::open (no PtexCache).
#include <Ptexture.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <time.h>
#include <vector>

#include "harness.h"

namespace {

const char* const kNames[8] = {"point", "bilinear", "box", "gaussian",
                               "bicubic", "bspline", "catmullrom", "mitchell"};
const PtexFilter::FilterType kTypes[8] = {
    PtexFilter::f_point,   PtexFilter::f_bilinear, PtexFilter::f_box,
    PtexFilter::f_gaussian, PtexFilter::f_bicubic, PtexFilter::f_bspline,
    PtexFilter::f_catmullrom, PtexFilter::f_mitchell};

struct Query {
    int face;
    float u, v, uw1, vw1, uw2, vw2;
    int filter;
    int nref;
    float ref[4];
    std::string reftext[4];
    std::string head;   // the line up to and including the filter name
};

double now_thread() { return harness_clock(CLOCK_THREAD_CPUTIME_ID); }

int usage()
{
    fprintf(stderr, "usage: ptexq FILE.ptx QUERIES.txt [--dump OUT] [--values OUT] [--reps N]"
                    " [--min-ms M] [--whole] [--check] [--sharpness S] [--width W] [--blur B]"
                    " [--lerp] [--noedgeblend]\n");
    return 2;
}

bool parse_line(const char* line, Query& q)
{
    const char* p = line + strspn(line, " \t\r\n");
    if (!*p || *p == '#') return false;
    char fn[32];
    int n = 0;
    if (sscanf(p, "%d %f %f %f %f %f %f %31s%n", &q.face, &q.u, &q.v, &q.uw1, &q.vw1, &q.uw2,
               &q.vw2, fn, &n) != 8) {
        fprintf(stderr, "bad line: %s", line);
        exit(1);
    }
    q.filter = -1;
    for (int i = 0; i < 8; i++)
        if (!strcmp(fn, kNames[i])) q.filter = i;
    if (q.filter < 0) {
        fprintf(stderr, "unknown filter %s\n", fn);
        exit(1);
    }
    q.head.assign(p, (size_t)n);
    q.nref = 0;
    const char* a = strstr(p + n, "->");
    if (a) {
        a += 2;
        char tok[64];
        int m;
        while (q.nref < 4 && sscanf(a, "%63s%n", tok, &m) == 1) {
            q.reftext[q.nref] = tok;
            q.ref[q.nref] = strtof(tok, 0);
            q.nref++;
            a += m;
        }
    }
    return true;
}

}  // namespace

int main(int argc, char** argv)
{
    if (argc < 3) return usage();
    const char* ptx = argv[1];
    const char* qfile = argv[2];
    const char* dump = 0;
    const char* values = 0;
    int reps = 3;
    double min_s = 0.015;
    bool whole = false, check = false, lerp = false, noedgeblend = false;
    float sharpness = 0.0f, width = 1.0f, blur = 0.0f;
    for (int i = 3; i < argc; i++) {
        std::string a = argv[i];
        if (a == "--dump" && i + 1 < argc) dump = argv[++i];
        else if (a == "--values" && i + 1 < argc) values = argv[++i];
        else if (a == "--reps" && i + 1 < argc) reps = atoi(argv[++i]);
        else if (a == "--min-ms" && i + 1 < argc) min_s = atof(argv[++i]) * 1e-3;
        else if (a == "--whole") whole = true;
        else if (a == "--check") check = true;
        else if (a == "--lerp") lerp = true;
        else if (a == "--noedgeblend") noedgeblend = true;
        else if (a == "--sharpness" && i + 1 < argc) sharpness = strtof(argv[++i], 0);
        else if (a == "--width" && i + 1 < argc) width = strtof(argv[++i], 0);
        else if (a == "--blur" && i + 1 < argc) blur = strtof(argv[++i], 0);
        else return usage();
    }
    if (reps < 0 || reps > 99) reps = 3;
    if (!(sharpness >= 0.0f && sharpness <= 1.0f) || !(width >= 0.0f) || !(blur >= 0.0f))
        return usage();
    if (width == 0.0f) width = 1.0f;

    FILE* fp = fopen(qfile, "r");
    if (!fp) { fprintf(stderr, "%s: cannot open\n", qfile); return 1; }
    std::vector<Query> Q;
    char line[1024];
    while (fgets(line, sizeof line, fp)) {
        Query q;
        if (parse_line(line, q)) Q.push_back(q);
    }
    fclose(fp);

    Ptex::String err;
    PtexTexture* tx = PtexTexture::open(ptx, err, false);
    if (!tx) { fprintf(stderr, "%s: %s\n", ptx, err.c_str()); return 1; }
    const int nc = tx->numChannels();
    const int nq = (int)Q.size();
    for (int i = 0; i < nq; i++)
        if (Q[i].face < 0 || Q[i].face >= tx->numFaces()) {
            fprintf(stderr, "query %d names face %d of %d\n", i + 1, Q[i].face, tx->numFaces());
            return 1;
        }

    PtexFilter* filt[8];
    for (int f = 0; f < 8; f++) {
        PtexFilter::Options opts(kTypes[f], lerp, sharpness, noedgeblend);
        filt[f] = PtexFilter::getFilter(tx, opts);
    }

    // outputs (first pass, untimed: also loads the face data the queries touch)
    std::vector<float> out((size_t)nq * 4, 0.0f);
    for (int i = 0; i < nq; i++) {
        const Query& q = Q[i];
        filt[q.filter]->eval(&out[(size_t)i * 4], 0, nc, q.face, q.u, q.v, q.uw1, q.vw1, q.uw2,
                             q.vw2, width, blur);
    }

    int rc = 0;
    if (dump) {
        FILE* d = fopen(dump, "w");
        if (!d) { fprintf(stderr, "%s: cannot write\n", dump); return 1; }
        for (int i = 0; i < nq; i++) {
            fprintf(d, "%s ->", Q[i].head.c_str());
            for (int c = 0; c < nc; c++) fprintf(d, " %.9g", (double)out[(size_t)i * 4 + c]);
            fprintf(d, "\n");
        }
        if (fclose(d)) rc = 1;
    }
    if (values) {
        FILE* d = fopen(values, "w");
        if (!d) { fprintf(stderr, "%s: cannot write\n", values); return 1; }
        for (int i = 0; i < nq; i++) {
            for (int c = 0; c < nc; c++)
                fprintf(d, "%s%.9g", c ? " " : "", (double)out[(size_t)i * 4 + c]);
            fprintf(d, "\n");
        }
        if (fclose(d)) rc = 1;
    }
    if (check) {
        float tol = tx->dataType() == Ptex::dt_uint8 ? 0.5f / 255.0f : 1e-4f;
        int withref = 0, exact = 0, intol = 0;
        float maxd = 0;
        for (int i = 0; i < nq; i++) {
            const Query& q = Q[i];
            if (!q.nref) continue;
            withref++;
            bool ex = true, ok = true;
            for (int c = 0; c < q.nref && c < nc; c++) {
                char buf[64];
                snprintf(buf, sizeof buf, "%.9g", (double)out[(size_t)i * 4 + c]);
                ex = ex && q.reftext[c] == buf;
                float d = std::fabs(out[(size_t)i * 4 + c] - q.ref[c]);
                if (!(d <= tol)) ok = false;
                if (d > maxd) maxd = d;
            }
            exact += ex;
            intol += ok;
        }
        printf("check %s: %d lines with reference values, %d exact (%%.9g text), %d within "
               "tolerance %g, max |diff| %g\n", qfile, withref, exact, intol, (double)tol,
               (double)maxd);
        if (intol != withref) rc = 1;
    }

    if (reps > 0) {
        float res[4];
        // batches: per filter (bench_ptex's grouping) or the whole list
        std::vector<std::vector<int> > groups;
        std::vector<int> gfilter;
        if (whole) {
            groups.push_back(std::vector<int>());
            for (int i = 0; i < nq; i++) groups[0].push_back(i);
            gfilter.push_back(-1);
        }
        else {
            for (int f = 0; f < 8; f++) {
                std::vector<int> g;
                for (int i = 0; i < nq; i++)
                    if (Q[i].filter == f) g.push_back(i);
                if (!g.empty()) { groups.push_back(g); gfilter.push_back(f); }
            }
        }
        printf("%s on %s (Ptex %d.%d, PtexFilter::eval), %d queries, %s, median of %d runs of "
               ">= %.0f ms (thread CPU time)\n", qfile, ptx, PtexLibraryMajorVersion,
               PtexLibraryMinorVersion, nq,
               whole ? "the whole list in file order as one batch"
                     : "per filter its lines in file order as one batch",
               reps, min_s * 1e3);
        printf("%-10s %8s %12s %10s\n", "filter", "queries", "M queries/s", "ns/query");
        double total_s = 0;
        long total_n = 0;
        for (size_t g = 0; g < groups.size(); g++) {
            const std::vector<int>& G = groups[g];
            const int m = (int)G.size();
            long iters = 1;
            std::vector<double> t;
            // the group's queries iters times over: thread CPU seconds
            auto timed = [&](long iters) {
                double t0 = now_thread();
                for (long k = 0; k < iters; k++)
                    for (int j = 0; j < m; j++) {
                        const Query& q = Q[G[j]];
                        filt[q.filter]->eval(res, 0, nc, q.face, q.u, q.v, q.uw1, q.vw1, q.uw2,
                                             q.vw2, width, blur);
                    }
                return now_thread() - t0;
            };
            for (;;) {
                double d = timed(iters);
                if (d >= min_s || iters > (1L << 30)) { t.push_back(d); break; }
                iters = d <= 0 ? iters * 8 : (long)((double)iters * min_s * 1.2 / d) + 1;
            }
            for (int r = 1; r < reps; r++)
                t.push_back(timed(iters));
            double mq = (double)m * (double)iters / harness_median(t) / 1e6;
            total_s += (double)m / (mq * 1e6);
            total_n += m;
            printf("%-10s %8d %12.2f %10.1f\n", gfilter[g] < 0 ? "whole" : kNames[gfilter[g]], m,
                   mq, 1e3 / mq);
        }
        double all = total_n ? (double)total_n / total_s / 1e6 : 0;
        printf("%-10s %8ld %12.2f %10.1f\n", "all", total_n, all, total_n ? 1e3 / all : 0.0);
    }

    for (int f = 0; f < 8; f++) filt[f]->release();
    tx->release();
    return rc;
}
