/* client/cli_sample.c - `seamtex sample`: one query from the arguments or many from a file
 * of text lines "face u v [dudx dvdx dudy dvdy]" (or, with --dir, cube-map directions
 * "x y z [ddx(3) ddy(3)]"), answered as text (one line per query: values, coverage, status)
 * or as raw binary values on stdout.
 *
 * Owns: the query file parser and the output formats. Does not own: sampling (the server),
 * framing (libseamtex), the names of modes, filters, formats and query statuses (the
 * protocol's lists, protocol/proto_lists.h); batches larger than the server's max_batch are
 * split by libseamtex. A query file on a unix: host is sent through a shared-memory region
 * (--shm, attach_shm below: the region's size; libseamtex does the rest).
 */
#include "cli.h"

#include <ctype.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "proto.h"
#include "unixaddr.h"

#define MAX_FILE_QUERIES (16u << 20)    /* 16 M queries (448 MiB of queries) at most */

static const char *const SAMPLE_USAGE =
"usage: seamtex sample SET FACE U V [options]\n"
"       seamtex sample SET --queries FILE [options]\n"
"       seamtex sample SET --dir X Y Z [--cone RADIANS] [options]     (cube maps)\n"
"       seamtex sample SET --dir --queries FILE [options]  lines 'x y z [ddx(3) ddy(3)]'\n"
"Samples a set. FILE has one query per line, 'face u v [dudx dvdx dudy dvdy]' ('-' reads\n"
"stdin; '#' starts a comment). Text output: one line per query with the channel values,\n"
"the coverage and the status.\n"
"  --dudx A --dvdx B --dudy C --dvdy D   footprint of a single query (default 0)\n"
"  --cone A           with --dir: a cone footprint of full angle A radians for every query\n"
"  --mode discard|traverse|clamp          seam handling (traverse)\n"
"  --filter NAME      point bilinear trilinear aniso, ptex-point ptex-bilinear ptex-box\n"
"                     ptex-gaussian ptex-bicubic ptex-bspline ptex-catmullrom\n"
"                     ptex-mitchell (bilinear)\n"
"  --zero-rule nan|clamp  a query whose taps all fall outside (discard) (nan)\n"
"  --max-aniso N  --sharpness S  --width W  --blur B\n"
"  --lerp             Ptex's lerp option: the ptex-gaussian and bicubic-family kernels\n"
"                     blended toward the next lower resolution (not with --dir)\n"
"  --binary           write the values raw (native byte order, count x channels) to stdout\n"
"  --format f32|unorm8|unorm16|f16   value format on the wire and in --binary output\n"
"                     (f32; f16 travels as binary16 and is written as f32)\n"
"  --compact          send the queries compact (PROTOCOL.md 4.4.1): u, v rounded to\n"
"                     multiples of 2^-16, derivatives to binary16\n"
"  --shm auto|on|off  with --queries on a unix: host: queries and values through a\n"
"                     shared-memory region (PROTOCOL.md 4.12); auto (default): when the\n"
"                     daemon allows it, else the socket; on: no region is an error\n";

enum { SHM_OFF, SHM_AUTO, SHM_ON };

/* --shm: attaches a region to ctx->conn for one call of `chunk` queries, which libseamtex
 * sends as parts of at most max_batch queries, up to 16 outstanding: room for all parts and one
 * more (the reply last read in place), each as libseamtex counts a SAMPLE_DIR part
 * (stc_shm_request_bytes: the larger query form). Under auto a refusal
 * (a TCP host, no SHM capability, over the daemon's shm-max) leaves the socket; under on it is
 * an error.
 * CLI_OK or an exit code (printed). */
static int attach_shm(cli_ctx *ctx, int policy, size_t chunk, unsigned outfmt)
{
    if (policy == SHM_OFF || ctx->conn_borrowed)
        return CLI_OK;
    if (policy == SHM_AUTO && !stu_is_unix_addr(ctx->host))
        return CLI_OK;
    size_t per = stc_server_info(ctx->conn)->max_batch;
    if (per == 0 || per > chunk)
        per = chunk;
    size_t bytes = stc_shm_request_bytes(1, per, outfmt) * ((chunk + per - 1) / per + 1);
    int rc = stc_shm_attach(ctx->conn, bytes);
    /* STC_ESTATE: interactive mode's connection has its region from an earlier command (the
     * CLI never leaves pipelined replies unread, the other cause) */
    if (rc == 0 || rc == STC_ESTATE || (policy == SHM_AUTO && !stc_error(ctx->conn)))
        return CLI_OK;
    return cli_fail(ctx, "--shm on", rc);
}

/* Reads a query file of either kind into *out (elements of `size` bytes). */
static int read_lines(const char *path, int dir, void **out, size_t *count)
{
    FILE *f = strcmp(path, "-") ? fopen(path, "r") : stdin;
    if (!f) {
        fprintf(stderr, "seamtex sample: %s: cannot open\n", path);
        return CLI_SERVER;
    }
    size_t size = dir ? sizeof(stc_dir_query) : sizeof(stc_query);
    uint8_t *q = NULL;
    size_t n = 0, cap = 0, lineno = 0;
    char *line = NULL;
    size_t lcap = 0;
    int rc = CLI_OK;
    while (getline(&line, &lcap, f) > 0) {
        lineno++;
        union { stc_query f; stc_dir_query d; } one;
        int r = dir ? cli_dir_query_line(line, &one.d) : cli_query_line(line, &one.f);
        if (r < 0) {
            fprintf(stderr, "seamtex sample: %s:%zu: expected '%s'\n", path, lineno,
                    dir ? "x y z [ddx0 ddx1 ddx2 ddy0 ddy1 ddy2]"
                        : "face u v [dudx dvdx dudy dvdy]");
            rc = CLI_USAGE;
            break;
        }
        if (r == 0)
            continue;
        if (n == MAX_FILE_QUERIES) {
            fprintf(stderr, "seamtex sample: %s: more than %u queries\n", path, MAX_FILE_QUERIES);
            rc = CLI_USAGE;
            break;
        }
        if (n == cap) {
            size_t nc = cap ? cap * 2 : 1024;
            uint8_t *p = realloc(q, nc * size);
            if (!p) {
                fprintf(stderr, "seamtex sample: out of memory\n");
                rc = CLI_SERVER;
                break;
            }
            q = p;
            cap = nc;
        }
        memcpy(q + n * size, &one, size);
        n++;
    }
    free(line);
    if (f != stdin)
        fclose(f);
    if (rc == CLI_OK && n == 0) {
        fprintf(stderr, "seamtex sample: %s has no query\n", path);
        rc = CLI_USAGE;
    }
    if (rc != CLI_OK) {
        free(q);
        return rc;
    }
    *out = q;
    *count = n;
    return CLI_OK;
}

/* A query number as the shortest of %g and %.9g that reads back as the float sent, so the
 * echoed query is the one sampled (10000.001 is past the 1e4 limit; %g printed "10000"). */
static void print_qnum(const char *sep, float x)
{
    char b[32];
    snprintf(b, sizeof b, "%g", x);
    if (x == x && strtof(b, NULL) != x)
        snprintf(b, sizeof b, "%.9g", x);
    printf("%s%s", sep, b);
}

/* One text line per query: the query, the values, the coverage and the status. */
static void print_text(const void *queries, int dir, const stc_sample_result *r)
{
    for (uint32_t i = 0; i < r->count; i++) {
        if (dir) {
            const stc_dir_query *q = (const stc_dir_query *)queries + i;
            print_qnum("", q->dir[0]);
            print_qnum(" ", q->dir[1]);
            print_qnum(" ", q->dir[2]);
            printf(":");
        } else {
            const stc_query *q = (const stc_query *)queries + i;
            printf("%u", q->face);
            print_qnum(" ", q->u);
            print_qnum(" ", q->v);
            printf(":");
        }
        for (unsigned c = 0; c < r->nchan; c++) {
            size_t k = (size_t)i * r->nchan + c;
            if (r->outfmt == STC_OUT_UNORM8)
                printf(" %u", ((const uint8_t *)r->values)[k]);
            else if (r->outfmt == STC_OUT_UNORM16)
                printf(" %u", ((const uint16_t *)r->values)[k]);
            else
                printf(" %.6g", ((const float *)r->values)[k]);
        }
        if (r->coverage)
            printf("  coverage %.4g", r->coverage[i]);
        if (r->status)
            printf("  %s", stp_qstatus_name(r->status[i]));
        printf("\n");
    }
}

int cli_cmd_sample(cli_ctx *ctx, int argc, char **argv)
{
    stc_sample_opts o;
    memset(&o, 0, sizeof o);
    o.mode = STP_MODE_TRAVERSE;
    o.filter = STP_FILTER_BILINEAR;
    const char *pos[4];
    int npos = 0, binary = 0, dir = 0, shm = SHM_AUTO, lerp = 0;
    const char *qfile = NULL, *set = NULL;
    stc_query one;
    stc_dir_query onedir;
    float cone = 0.0f;
    int have_cone = 0;
    memset(&one, 0, sizeof one);
    memset(&onedir, 0, sizeof onedir);

    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (cli_is_help(a)) {
            fputs(SAMPLE_USAGE, stdout);
            return CLI_OK;
        }
        float num;   /* a negative number is a value, "-inf" and "-nan" too (as "inf", "nan") */
        if (a[0] != '-' || a[1] == '\0' || cli_parse_float(a, &num) == 0) {
            if (!set)
                set = a;
            else if (npos < 4)
                pos[npos++] = a;
            else {
                fprintf(stderr, "seamtex sample: too many arguments (see --help)\n");
                return CLI_USAGE;
            }
            continue;
        }
        if (!strcmp(a, "--binary")) {
            binary = 1;
            continue;
        }
        if (!strcmp(a, "--dir")) {
            dir = 1;
            continue;
        }
        if (!strcmp(a, "--lerp")) {
            lerp = 1;
            continue;
        }
        if (!strcmp(a, "--compact")) {
            o.want |= STC_WANT_UV16;
            continue;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "seamtex sample: %s needs a value\n", a);
            return CLI_USAGE;
        }
        const char *v = argv[++i];
        int bad = 0;
        uint32_t u;
        float *fp = !strcmp(a, "--dudx") ? &one.dudx : !strcmp(a, "--dvdx") ? &one.dvdx
                  : !strcmp(a, "--dudy") ? &one.dudy : !strcmp(a, "--dvdy") ? &one.dvdy
                  : !strcmp(a, "--sharpness") ? &o.sharpness : !strcmp(a, "--width") ? &o.width
                  : !strcmp(a, "--blur") ? &o.blur : !strcmp(a, "--cone") ? &cone : NULL;
        if (fp) {
            bad = cli_parse_float(v, fp);
            have_cone |= fp == &cone;
        } else if (!strcmp(a, "--queries")) {
            qfile = v;
        } else if (!strcmp(a, "--mode")) {
            int m = stp_mode_parse(v);
            bad = m < 0;
            o.mode = (unsigned)m;
        } else if (!strcmp(a, "--filter")) {
            int f = stp_filter_parse(v);
            bad = f < 0;
            o.filter = (unsigned)f;
        } else if (!strcmp(a, "--zero-rule")) {
            int z = stp_zero_rule_parse(v);
            bad = z < 0;
            o.zero_rule = bad ? 0 : (unsigned)z;
        } else if (!strcmp(a, "--max-aniso")) {
            bad = cli_parse_u32(v, &u) || u > 16;
            o.max_aniso = u;
        } else if (!strcmp(a, "--format")) {
            int f = stp_outfmt_parse(v);
            bad = f < 0;
            o.outfmt = bad ? 0 : (unsigned)f;
        } else if (!strcmp(a, "--shm")) {
            shm = !strcmp(v, "auto") ? SHM_AUTO : !strcmp(v, "on") ? SHM_ON
                : !strcmp(v, "off") ? SHM_OFF : -1;
            bad = shm < 0;
        } else {
            fprintf(stderr, "seamtex sample: unknown option %s (see --help)\n", a);
            return CLI_USAGE;
        }
        if (bad) {
            fprintf(stderr, "seamtex sample: bad value for %s: '%s'\n", a, v);
            return CLI_USAGE;
        }
    }
    if (have_cone && !dir) {
        fprintf(stderr, "seamtex sample: --cone is a footprint of --dir queries\n");
        return CLI_USAGE;
    }
    if (!set || (qfile && npos) || (!qfile && npos != 3)) {
        fputs(SAMPLE_USAGE, stderr);
        return CLI_USAGE;
    }
    if (dir && (o.want & STC_WANT_UV16)) {
        fprintf(stderr, "seamtex sample: --compact is for face queries, not --dir (PROTOCOL.md "
                        "4.4.1: the compact layouts are SAMPLE's)\n");
        return CLI_USAGE;
    }
    if (dir && lerp) {   /* refused here like --compact, not sent for the server's INVALID */
        fprintf(stderr, "seamtex sample: --lerp is for face queries, not --dir (the lerp flag "
                        "is SAMPLE's, PROTOCOL.md 4.4)\n");
        return CLI_USAGE;
    }
    if (binary && isatty(STDOUT_FILENO)) {
        fprintf(stderr, "seamtex sample: --binary output is not for a terminal; redirect it\n");
        return CLI_USAGE;
    }

    void *q = dir ? (void *)&onedir : (void *)&one;
    size_t n = 1;
    if (qfile) {
        int rc = read_lines(qfile, dir, &q, &n);
        if (rc)
            return rc;
    } else if (dir ? cli_parse_float(pos[0], &onedir.dir[0]) ||
                     cli_parse_float(pos[1], &onedir.dir[1]) ||
                     cli_parse_float(pos[2], &onedir.dir[2])
                   : cli_parse_u32(pos[0], &one.face) || cli_parse_float(pos[1], &one.u) ||
                     cli_parse_float(pos[2], &one.v)) {
        fprintf(stderr, "seamtex sample: %s must be numbers\n", dir ? "X Y Z" : "FACE U V");
        return CLI_USAGE;
    }
    if (dir && have_cone) {
        /* a cone footprint: ddx[0] is the full angle, the other five floats are 0 (a NaN or
         * negative angle goes as it is: the server answers NONFINITE / BAD_FOOTPRINT) */
        o.footprint = 1;
        stc_dir_query *d = q;
        for (size_t i = 0; i < n; i++) {
            memset(d[i].ddx, 0, sizeof d[i].ddx);
            memset(d[i].ddy, 0, sizeof d[i].ddy);
            d[i].ddx[0] = cone;
        }
    }
    /* --compact's bits stay; coverage and status only for the text output */
    o.want = (o.want & (STC_WANT_UV16 | STC_WANT_FACE16)) |
             (binary ? 0 : STC_WANT_COVERAGE | STC_WANT_STATUS);
    if (lerp)
        o.want |= STC_WANT_LERP;

    int rc = cli_connect(ctx);
    if (rc)
        goto out;
    size_t chunk = stc_server_info(ctx->conn)->max_batch;
    if (chunk == 0 || chunk > 65536)
        chunk = 65536;
    if (qfile && (rc = attach_shm(ctx, shm, n < chunk ? n : chunk, o.outfmt)) != CLI_OK)
        goto out;
    size_t qsize = dir ? sizeof(stc_dir_query) : sizeof(stc_query);
    uint64_t nbad = 0;
    for (size_t at = 0; at < n; at += chunk) {
        size_t m = n - at < chunk ? n - at : chunk;
        const void *qa = (const uint8_t *)q + at * qsize;
        stc_sample_result r;
        int e = dir ? stc_sample_dir(ctx->conn, set, &o, qa, m, &r)
                    : stc_sample(ctx->conn, set, &o, qa, m, &r);
        if (e) {
            rc = cli_fail(ctx, set, e);
            goto out;
        }
        nbad += r.nbad;
        if (binary) {
            size_t vs = r.outfmt == STC_OUT_F32 || r.outfmt == STC_OUT_F16 ? 4
                        : r.outfmt == STC_OUT_UNORM16 ? 2 : 1;
            size_t bytes = (size_t)r.count * r.nchan * vs;
            if (fwrite(r.values, 1, bytes, stdout) != bytes) {
                fprintf(stderr, "seamtex sample: writing the output failed\n");
                rc = CLI_SERVER;
                goto out;
            }
        } else {
            print_text(qa, dir, &r);
        }
    }
    if (!binary && n > 1)
        printf("(%zu queries, %llu not OK)\n", n, (unsigned long long)nbad);
out:
    if (q != &one && q != &onedir)
        free(q);
    return rc;
}
