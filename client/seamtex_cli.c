/* client/seamtex_cli.c - `seamtex`, the command-line client (in the spirit of redis-cli):
 *
 *   seamtex [-h host] [-p port] [-t token] [--timeout ms] <command> [args]
 *   ping | ls | info SET | sample ... | upload ... | delete SET | stats | fetch ... | compress ...
 *
 * Owns: global options, dispatch, exit codes, the small commands (ping, ls, info, stats,
 * delete), shared helpers (cli.h). Does not own: the protocol or connections (libseamtex);
 * sample (cli_sample.c); upload, fetch, compress (cli_transfer.c).
 *
 * Exit codes: 0 ok, 1 the server refused (or a local file failed), 2 usage, 3 connection.
 * Output for people goes to stdout; errors and progress to stderr.
 */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "proto.h"
#include "unixaddr.h"
#include "seamtex_cluster.h"
#include "stp_cluster.h"

#define DEFAULT_PORT 7450

static const char *const USAGE =
"usage: seamtex [-h HOST] [-p PORT] [-t TOKEN] [--timeout MS] [--cluster HOST:PORT,...|URL]\n"
"               COMMAND [ARGS]\n"
"\n"
"  ping                         round trip to the server, prints the time it took\n"
"  ls [--json]                  the sets the server holds\n"
"  info SET [--faces A:N] [--json]  facts about a set (and per-face records A..A+N-1)\n"
"  sample SET FACE U V [opts]   sample one point, or --queries FILE; text or --binary\n"
"  upload FILE NAME [opts]      upload a file as set NAME (progress bar on stderr)\n"
"  delete SET                   remove a set\n"
"  stats [--json]               the server's counters\n"
"  fetch SET FILE [--format F]   download a set as a file (format from FILE's extension)\n"
"  compress SET TARGET [opts]   BC1-compress a set into TARGET (progress, report)\n"
"  cluster [--json]             the cluster's nodes, sets per node, under-replicated sets\n"
"\n"
"--cluster HOST:PORT,... (seed nodes of a cluster) or etcd://HOST:PORT[,...]/PREFIX (the\n"
"cluster's etcd: its registered nodes are the seeds): a command that reads a set goes to a\n"
"node that serves it, upload and delete to the set's first reachable owner (docs/cluster.md);\n"
"`cluster` asks the seeds; `ls` lists every node's sets, each once.\n"
"Without a COMMAND, commands are read one per line from stdin (a prompt on a terminal),\n"
"over one connection, like redis-cli; 'quit' or end of input stops.\n"
"-h, -p, -t are also --host, --port, --token. HOST defaults to $SEAMTEX_HOST or 127.0.0.1,\n"
"PORT to $SEAMTEX_PORT or 7450, TOKEN to $SEAMTEX_TOKEN; HOST unix:/path connects to a\n"
"daemon's Unix socket (PORT unused).\n"
"`seamtex COMMAND --help` describes a command. --json (ls, info, stats,\n"
"compress, cluster) prints one JSON document instead of text (keys: seamtex(1), docs/client.md).\n"
"Exit status: 0 ok, 1 the server refused or a file failed, 2 usage, 3 connection.\n";

/* ---- shared helpers (cli.h) --------------------------------------------------------------- */

int cli_is_help(const char *a)
{
    return !strcmp(a, "--help") || !strcmp(a, "-?");
}

int cli_json_finish(cli_json *j)
{
    if (cli_json_end(j) != 0) {
        fprintf(stderr, "seamtex: writing the JSON output failed\n");
        return CLI_SERVER;
    }
    return CLI_OK;
}

/* The options of a command that takes none but --json: 1 with --json, 0 without, -1 after
 * printing the usage (to stdout for --help: *rc = CLI_OK, else stderr and CLI_USAGE). */
static int json_only_args(int argc, char **argv, const char *usage, int *rc)
{
    int json = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json")) {
            json = 1;
            continue;
        }
        int help = cli_is_help(argv[i]);
        fputs(usage, help ? stdout : stderr);
        *rc = help ? CLI_OK : CLI_USAGE;
        return -1;
    }
    return json;
}

const char *cli_kind_name(unsigned kind)
{
    const char *n = stp_kind_name(kind);
    return n ? n : "?";
}

const char *cli_dtype_name(unsigned dtype)
{
    const char *n = stp_dtype_name(dtype);
    return n ? n : "?";
}

const char *cli_bytes(uint64_t n, char *buf, size_t cap)
{
    if (n < 1024)
        snprintf(buf, cap, "%llu B", (unsigned long long)n);
    else if (n < (1ull << 20))
        snprintf(buf, cap, "%.1f KiB", n / 1024.0);
    else if (n < (1ull << 30))
        snprintf(buf, cap, "%.1f MiB", n / 1048576.0);
    else
        snprintf(buf, cap, "%.2f GiB", n / 1073741824.0);
    return buf;
}

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

void cli_progress_init(cli_progress *p, const char *what, int bytes)
{
    p->what = what;
    p->bytes = bytes;
    p->tty = isatty(STDERR_FILENO);
    p->last = -1;
    p->t0 = now_ns();
}

void cli_progress_update(cli_progress *p, uint64_t done, uint64_t total)
{
    int pct = total ? (int)(done * 100 / total) : 100;
    if (pct > 100)
        pct = 100;
    if (p->tty) {
        if (pct == p->last)
            return;
        double secs = (now_ns() - p->t0) / 1e9;
        double rate = secs > 0 ? done / secs : 0;
        char a[32], b[32], r[32];
        int width = 30, fill = pct * width / 100;
        fprintf(stderr, "\r%s [", p->what);
        for (int i = 0; i < width; i++)
            fputc(i < fill ? '#' : '.', stderr);
        fprintf(stderr, "] %3d%%", pct);
        if (p->bytes)
            fprintf(stderr, " %s / %s  %s/s ", cli_bytes(done, a, sizeof a),
                    cli_bytes(total, b, sizeof b), cli_bytes((uint64_t)rate, r, sizeof r));
        else
            fprintf(stderr, "  %.1f s ", secs);
        fflush(stderr);
    } else {
        if (p->last >= 0 && pct / 10 == p->last / 10 && pct != 100)
            return;
        if (pct == p->last)
            return;
        fprintf(stderr, "%s: %d%%\n", p->what, pct);
    }
    p->last = pct;
}

void cli_progress_end(cli_progress *p)
{
    if (p->tty && p->last >= 0)
        fputc('\n', stderr);
}

int cli_check_env_port(const cli_ctx *ctx)
{
    if (ctx->bad_env_port && !stu_is_unix_addr(ctx->host)) {   /* not 7450 behind one's back */
        fprintf(stderr, "%s: bad SEAMTEX_PORT '%s': not a port 1..65535\n", ctx->prog,
                ctx->bad_env_port);
        return CLI_USAGE;
    }
    return CLI_OK;
}

void cli_conn_opts(const cli_ctx *ctx, stc_opts *o)
{
    memset(o, 0, sizeof *o);
    o->token = ctx->token;
    o->client_name = "seamtex-cli";
    o->request_timeout_ms = ctx->timeout_ms;
    o->connect_timeout_ms = ctx->timeout_ms;   /* --timeout bounds the connect and HELLO too;
                                                  0: the library's 5 s (the cluster's 2 s) */
}

int cli_connect(cli_ctx *ctx)
{
    if (ctx->cluster_seeds && ctx->route_set) {   /* --cluster: the set's owner */
        if (ctx->conn && !ctx->conn_borrowed)
            stc_close(ctx->conn);
        ctx->conn = NULL;
        return cli_connect_routed(ctx, ctx->route_set);
    }
    if (ctx->conn) {                        /* interactive mode keeps one connection */
        if (stc_error(ctx->conn) == 0)
            return CLI_OK;
        stc_close(ctx->conn);
        ctx->conn = NULL;
    }
    int rc = cli_check_env_port(ctx);
    if (rc)
        return rc;
    stc_opts o;
    cli_conn_opts(ctx, &o);
    char msg[256] = "";
    int err = 0;
    ctx->conn = stc_connect_opts(ctx->host, ctx->port, &o, &err, msg, sizeof msg);
    if (!ctx->conn) {
        if (stu_is_unix_addr(ctx->host))   /* msg names the path already */
            fprintf(stderr, "%s: cannot connect: %s%s%s\n", ctx->prog, stc_strerror(err),
                    msg[0] ? ": " : "", msg);
        else
            fprintf(stderr, "%s: cannot connect to %s:%u: %s%s%s\n", ctx->prog, ctx->host,
                    ctx->port, stc_strerror(err), msg[0] ? ": " : "", msg);
        return CLI_CONNECT;
    }
    return CLI_OK;
}

int cli_fail(cli_ctx *ctx, const char *what, int code)
{
    const char *m = ctx->conn ? stc_errmsg(ctx->conn) : "";
    /* PERM after a HELLO that carried a token: the token was wrong, not missing */
    const char *wrong = code == STC_EPERM && ctx->token && ctx->conn &&
                        !stc_server_info(ctx->conn)->authenticated
                        ? " (the token given, -t or $SEAMTEX_TOKEN, was not accepted)" : "";
    if (stc_is_server_error(code) && m && *m)   /* the library's "OPCODE: STATUS: text" */
        fprintf(stderr, "%s: %s: %s%s\n", ctx->prog, what, m, wrong);
    else
        fprintf(stderr, "%s: %s: %s%s%s\n", ctx->prog, what, stc_strerror(code),
                m && *m ? ": " : "", m ? m : "");
    if (stc_is_server_error(code))
        return CLI_SERVER;
    switch (code) {
    case STC_EINVAL:
        return CLI_USAGE;
    case STC_EFILE: case STC_ECHECKSUM: case STC_ECANCELED: case STC_ENOMEM: case STC_ESTATE:
        return CLI_SERVER;
    default:
        return CLI_CONNECT;            /* EIO, ECLOSED, EPROTO, ETIMEDOUT, ECONNECT */
    }
}

/* ---- small commands ------------------------------------------------------------------------ */

static int cmd_ping(cli_ctx *ctx, int argc, char **argv)
{
    if (argc > 1) {
        fprintf(argc == 2 && cli_is_help(argv[1]) ? stdout : stderr,
                "usage: seamtex ping\nOne PING round trip; prints PONG and the time it took.\n");
        return argc == 2 && cli_is_help(argv[1]) ? CLI_OK : CLI_USAGE;
    }
    int rc = cli_connect(ctx);
    if (rc)
        return rc;
    uint64_t t0 = now_ns();
    int e = stc_ping(ctx->conn);
    if (e)
        return cli_fail(ctx, "ping", e);
    printf("PONG %.1f us\n", (now_ns() - t0) / 1e3);
    return CLI_OK;
}

static int print_sets(const stc_set_entry *s, size_t n, int json, int rc);

static int cmd_ls(cli_ctx *ctx, int argc, char **argv)
{
    int rc = CLI_OK;
    int json = json_only_args(argc, argv, "usage: seamtex ls [--json]\nLists the sets: name, "
                              "kind, channels, type, faces, memory. Under --cluster: every "
                              "node's sets, each once (exit 3 when a node does not answer).\n", &rc);
    if (json < 0)
        return rc;
    const stc_set_entry *s;
    size_t n;
    stc_set_entry *all = NULL;
    void *keep = NULL;
    if (ctx->cluster_seeds) {   /* the cluster's sets: every node's */
        rc = cli_cluster_list(ctx, &all, &n, &keep);
        if (!all)
            return rc;
        s = all;
    } else {
        rc = cli_connect(ctx);
        if (rc)
            return rc;
        int e = stc_list(ctx->conn, &s, &n);
        if (e)
            return cli_fail(ctx, "ls", e);
    }
    rc = print_sets(s, n, json, rc);
    free(all);
    free(keep);
    return rc;
}

/* ls's output: a table, or --json; rc is returned (the JSON writer's failure instead) */
static int print_sets(const stc_set_entry *s, size_t n, int json, int rc)
{
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_object(&j, NULL);
        cli_json_u64(&j, "count", n);
        cli_json_array(&j, "sets");
        for (size_t i = 0; i < n; i++) {
            cli_json_object(&j, NULL);
            cli_json_str(&j, "name", s[i].name);
            cli_json_str(&j, "kind", cli_kind_name(s[i].kind));
            cli_json_u64(&j, "channels", s[i].nchan);
            cli_json_str(&j, "type", cli_dtype_name(s[i].dtype));
            cli_json_u64(&j, "faces", s[i].nfaces);
            cli_json_u64(&j, "memory_bytes", s[i].memory);
            cli_json_close(&j);
        }
        cli_json_close(&j);
        cli_json_close(&j);
        int jr = cli_json_finish(&j);
        return jr ? jr : rc;
    }
    printf("%-32s %-8s %4s %-5s %9s %12s\n", "NAME", "KIND", "CHAN", "TYPE", "FACES", "MEMORY");
    for (size_t i = 0; i < n; i++) {
        char b[32];
        printf("%-32s %-8s %4u %-5s %9u %12s\n", s[i].name, cli_kind_name(s[i].kind), s[i].nchan,
               cli_dtype_name(s[i].dtype), s[i].nfaces, cli_bytes(s[i].memory, b, sizeof b));
    }
    printf("(%zu set%s)\n", n, n == 1 ? "" : "s");
    return rc;
}

/* `seamtex info --json`: the same facts as the text, sizes in bytes. */
static int info_json(const char *set, const stc_info *in)
{
    cli_json j;
    cli_json_begin(&j, stdout);
    cli_json_object(&j, NULL);
    cli_json_str(&j, "name", set);
    cli_json_str(&j, "kind", cli_kind_name(in->kind));
    cli_json_u64(&j, "faces", in->nfaces);
    cli_json_u64(&j, "constant_faces", in->nconstant);
    cli_json_u64(&j, "subfaces", in->nsubfaces);
    cli_json_u64(&j, "channels", in->nchan);
    cli_json_str(&j, "type", cli_dtype_name(in->dtype));
    cli_json_i64(&j, "alpha_channel", in->alpha_chan);
    cli_json_str(&j, "colorspace", in->colorspace ? "srgb" : "linear");
    cli_json_bool(&j, "premultiplied", in->premultiplied);
    cli_json_u64(&j, "min_width", in->min_w);
    cli_json_u64(&j, "min_height", in->min_h);
    cli_json_u64(&j, "max_width", in->max_w);
    cli_json_u64(&j, "max_height", in->max_h);
    cli_json_u64(&j, "memory_bytes", in->memory);
    cli_json_u64(&j, "texel_bytes", in->texel_bytes);
    cli_json_u64(&j, "boundary_edges", in->boundary_edges);
    cli_json_u64(&j, "irregular_corners", in->irregular_corners);
    cli_json_u64(&j, "max_valence", in->max_valence);
    cli_json_u64(&j, "border_u", in->border_u);
    cli_json_u64(&j, "border_v", in->border_v);
    cli_json_str(&j, "mesh", in->meshtype ? "triangle" : "quad");
    cli_json_str(&j, "edge_filter", in->edgefilter == 1 ? "tanvec" : "none");
    cli_json_u64(&j, "metadata_entries", in->nmeta);
    if (in->nrec) {
        cli_json_array(&j, "face_records");
        for (uint32_t i = 0; i < in->nrec; i++) {
            const stc_face *f = &in->faces[i];
            cli_json_object(&j, NULL);
            cli_json_u64(&j, "face", (uint64_t)in->face_first + i);
            cli_json_u64(&j, "width", f->w);
            cli_json_u64(&j, "height", f->h);
            cli_json_u64(&j, "levels", f->nlevels);
            cli_json_bool(&j, "constant", f->flags & 1);
            cli_json_array(&j, "adjacent");          /* edges 0..3: face (-1 none), edge */
            for (int k = 0; k < 4; k++) {
                cli_json_object(&j, NULL);
                cli_json_i64(&j, "face", f->adjface[k]);
                cli_json_u64(&j, "edge", f->adjface[k] < 0 ? 0u : f->adjedge[k]);
                cli_json_close(&j);
            }
            cli_json_close(&j);
            cli_json_close(&j);
        }
        cli_json_close(&j);
    }
    cli_json_close(&j);
    return cli_json_finish(&j);
}

static int cmd_info(cli_ctx *ctx, int argc, char **argv)
{
    const char *set = NULL;
    uint32_t first = 0, count = 0;
    int json = 0;
    for (int i = 1; i < argc; i++) {
        if (cli_is_help(argv[i])) {
            printf("usage: seamtex info SET [--faces FIRST:COUNT] [--json]\n"
                   "Facts about a set; --faces also prints per-face records (size, levels,\n"
                   "neighbours across edges 0..3 as face/edge, -1 on a boundary).\n");
            return CLI_OK;
        } else if (!strcmp(argv[i], "--json")) {
            json = 1;
        } else if (!strcmp(argv[i], "--faces") && i + 1 < argc) {
            char *colon = strchr(argv[++i], ':');
            if (!colon) {
                fprintf(stderr, "seamtex info: --faces wants FIRST:COUNT\n");
                return CLI_USAGE;
            }
            *colon = '\0';
            if (cli_parse_u32(argv[i], &first) || cli_parse_u32(colon + 1, &count) ||
                count > 100000) {
                fprintf(stderr, "seamtex info: bad --faces range\n");
                return CLI_USAGE;
            }
        } else if (!set && argv[i][0] != '-') {
            set = argv[i];
        } else {
            fprintf(stderr, "seamtex info: unexpected '%s' (see seamtex info --help)\n", argv[i]);
            return CLI_USAGE;
        }
    }
    if (!set) {
        fprintf(stderr, "usage: seamtex info SET [--faces FIRST:COUNT] [--json]\n");
        return CLI_USAGE;
    }
    int rc = cli_connect(ctx);
    if (rc)
        return rc;
    stc_info in;
    int e = stc_info_get(ctx->conn, set, first, count, &in);
    if (e)
        return cli_fail(ctx, set, e);
    if (json)
        return info_json(set, &in);
    char b1[32], b2[32];
    printf("name:              %s\n", set);
    printf("kind:              %s\n", cli_kind_name(in.kind));
    printf("faces:             %u (%u constant, %u subfaces)\n", in.nfaces, in.nconstant,
           in.nsubfaces);
    printf("channels:          %u %s%s\n", in.nchan, cli_dtype_name(in.dtype),
           in.alpha_chan >= 0 ? " (alpha)" : "");
    printf("colorspace:        %s%s\n", in.colorspace ? "srgb" : "linear",
           in.premultiplied ? ", premultiplied" : "");
    printf("face sizes:        %ux%u .. %ux%u\n", in.min_w, in.min_h, in.max_w, in.max_h);
    printf("memory:            %s (texels %s)\n", cli_bytes(in.memory, b1, sizeof b1),
           cli_bytes(in.texel_bytes, b2, sizeof b2));
    printf("boundary edges:    %u\n", in.boundary_edges);
    printf("irregular corners: %u (max valence %u)\n", in.irregular_corners, in.max_valence);
    printf("border modes:      u %u, v %u; mesh %s; edge filter %s\n", in.border_u,
           in.border_v, in.meshtype ? "triangle" : "quad", in.edgefilter == 1 ? "tanvec" : "none");
    printf("metadata entries:  %u\n", in.nmeta);
    for (uint32_t i = 0; i < in.nrec; i++) {
        const stc_face *f = &in.faces[i];
        printf("face %u: %ux%u levels %u%s adj", in.face_first + i, f->w, f->h, f->nlevels,
               f->flags & 1 ? " constant" : "");
        for (int k = 0; k < 4; k++)
            printf(" %d/%u", f->adjface[k], f->adjface[k] < 0 ? 0u : f->adjedge[k]);
        printf("\n");
    }
    return CLI_OK;
}

static int cmd_stats(cli_ctx *ctx, int argc, char **argv)
{
    int rc = CLI_OK;
    int json = json_only_args(argc, argv, "usage: seamtex stats [--json]\nThe server's "
                              "counters, one 'key value' per line (--json: one object).\n", &rc);
    if (json < 0)
        return rc;
    rc = cli_connect(ctx);
    if (rc)
        return rc;
    const stc_stat *s;
    size_t n;
    int e = stc_stats(ctx->conn, &s, &n);
    if (e)
        return cli_fail(ctx, "stats", e);
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_object(&j, NULL);
        for (size_t i = 0; i < n; i++) {
            if (s[i].is_float)
                cli_json_double(&j, s[i].key, s[i].f);
            else
                cli_json_u64(&j, s[i].key, s[i].u);
        }
        cli_json_close(&j);
        return cli_json_finish(&j);
    }
    for (size_t i = 0; i < n; i++) {
        if (s[i].is_float)
            printf("%-32s %.6g\n", s[i].key, s[i].f);
        else
            printf("%-32s %llu\n", s[i].key, (unsigned long long)s[i].u);
    }
    return CLI_OK;
}

static int cmd_delete(cli_ctx *ctx, int argc, char **argv)
{
    if (argc != 2 || cli_is_help(argv[1])) {
        int help = argc == 2 && cli_is_help(argv[1]);
        fprintf(help ? stdout : stderr, "usage: seamtex delete SET\nRemoves a set (needs the "
                "token when the server has one).\n");
        return help ? CLI_OK : CLI_USAGE;
    }
    int rc = cli_connect(ctx);
    if (rc)
        return rc;
    int e = stc_delete(ctx->conn, argv[1]);
    if (e)
        return cli_fail(ctx, argv[1], e);
    printf("deleted %s\n", argv[1]);
    return CLI_OK;
}

/* ---- main ------------------------------------------------------------------------------------ */

typedef struct cli_cmd {
    const char *name;
    int (*fn)(cli_ctx *, int, char **);
} cli_cmd;

static const cli_cmd CMDS[] = {
    { "ping", cmd_ping },          { "ls", cmd_ls },          { "list", cmd_ls },
    { "info", cmd_info },          { "sample", cli_cmd_sample },
    { "upload", cli_cmd_upload },  { "delete", cmd_delete },  { "rm", cmd_delete },
    { "stats", cmd_stats },        { "fetch", cli_cmd_fetch }, { "compress", cli_cmd_compress },
    { "cluster", cli_cmd_cluster },
};

static int dispatch(cli_ctx *ctx, int argc, char **argv)
{
    /* under --cluster a command that names a set is sent to that set's owner: the set is the
     * first word after the command (upload: the second) that is not an option */
    ctx->route_set = NULL;
    ctx->route_held = strcmp(argv[0], "upload") && strcmp(argv[0], "delete") &&
                      strcmp(argv[0], "rm");
    int want = !strcmp(argv[0], "upload") ? 2 : 1, seen = 0;
    if (strcmp(argv[0], "cluster") && strcmp(argv[0], "stats") && strcmp(argv[0], "ping") &&
        strcmp(argv[0], "ls") && strcmp(argv[0], "list"))
        for (int k = 1; k < argc && !ctx->route_set; k++)
            if (argv[k][0] != '-' && ++seen == want)
                ctx->route_set = argv[k];
    for (size_t k = 0; k < sizeof CMDS / sizeof CMDS[0]; k++)
        if (!strcmp(argv[0], CMDS[k].name))
            return CMDS[k].fn(ctx, argc, argv);
    fprintf(stderr, "seamtex: unknown command '%s'\n%s", argv[0], USAGE);
    return CLI_USAGE;
}

/* Splits a line into words (whitespace; "double" or 'single' quotes group), in place. */
static int split_words(char *line, char **argv, int max)
{
    int n = 0;
    char *p = line;
    for (;;) {
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
            p++;
        if (!*p)
            return n;
        if (n == max)
            return -1;
        char *w = p, *o = p;
        char quote = 0;
        for (; *p; p++) {
            if (quote) {
                if (*p == quote)
                    quote = 0;
                else
                    *o++ = *p;
            } else if (*p == '"' || *p == '\'') {
                quote = *p;
            } else if (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') {
                p++;
                break;
            } else {
                *o++ = *p;
            }
        }
        if (quote)
            return -1;
        *o = '\0';                          /* o never passes p: quotes only shrink */
        argv[n++] = w;
    }
}

/* Interactive (or piped) mode: one command per line over one connection. The exit status
 * is that of the last command that failed, 0 when none did. */
static int repl(cli_ctx *ctx)
{
    int tty = isatty(STDIN_FILENO) && isatty(STDOUT_FILENO);
    int last_bad = CLI_OK;
    char *line = NULL;
    size_t cap = 0;
    for (;;) {
        if (tty) {   /* a unix: host has no port (seamtex(1)) */
            if (stu_is_unix_addr(ctx->host))
                printf("seamtex %s> ", ctx->host);
            else
                printf("seamtex %s:%u> ", ctx->host, ctx->port);
            fflush(stdout);
        }
        if (getline(&line, &cap, stdin) < 0)
            break;
        char *argv[64];
        int argc = split_words(line, argv, 63);
        if (argc < 0) {
            fprintf(stderr, "seamtex: unbalanced quote or too many words\n");
            last_bad = CLI_USAGE;
            continue;
        }
        if (argc == 0 || argv[0][0] == '#')
            continue;
        if (!strcmp(argv[0], "quit") || !strcmp(argv[0], "exit"))
            break;
        if (!strcmp(argv[0], "help")) {
            fputs(USAGE, stdout);
            continue;
        }
        argv[argc] = NULL;
        int rc = dispatch(ctx, argc, argv);
        fflush(stdout);
        if (rc != CLI_OK)
            last_bad = rc;
    }
    if (tty)
        printf("\n");
    free(line);
    return last_bad;
}


/* rc, or CLI_SERVER when standard output could not be written (a full disk, a closed pipe) */
static int flushed(int rc)
{
    if (fflush(stdout) != 0 && rc == CLI_OK) {
        fprintf(stderr, "seamtex: writing the output failed\n");
        rc = CLI_SERVER;
    }
    return rc;
}

int main(int argc, char **argv)
{
    cli_ctx ctx = { .host = "127.0.0.1", .port = DEFAULT_PORT, .prog = "seamtex" };
    const char *env;
    if ((env = getenv("SEAMTEX_HOST")) && *env)
        ctx.host = env;
    if ((env = getenv("SEAMTEX_PORT")) && *env) {
        uint32_t p;
        if (cli_parse_u32(env, &p) == 0 && p > 0 && p < 65536)
            ctx.port = p;
        else
            ctx.bad_env_port = env;   /* refused when a command connects, unless -p */
    }
    if ((env = getenv("SEAMTEX_TOKEN")) && *env)
        ctx.token = env;

    int i = 1;
    for (; i < argc && argv[i][0] == '-'; i++) {
        const char *a = argv[i];
        if (cli_is_help(a)) {
            fputs(USAGE, stdout);
            return flushed(CLI_OK);
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "seamtex: option %s needs a value\n%s", a, USAGE);
            return CLI_USAGE;
        }
        const char *v = argv[++i];
        uint32_t u;
        if (!strcmp(a, "-h") || !strcmp(a, "--host")) {
            ctx.host = v;
        } else if (!strcmp(a, "-p") || !strcmp(a, "--port")) {
            if (cli_parse_u32(v, &u) || u == 0 || u > 65535) {
                fprintf(stderr, "seamtex: bad port '%s'\n", v);
                return CLI_USAGE;
            }
            ctx.port = u;
            ctx.bad_env_port = NULL;
        } else if (!strcmp(a, "-t") || !strcmp(a, "--token")) {
            ctx.token = v;
        } else if (!strcmp(a, "--cluster")) {
            ctx.cluster_seeds = v;
        } else if (!strcmp(a, "--timeout")) {
            if (cli_parse_u32(v, &u) || u > 86400000) {
                fprintf(stderr, "seamtex: bad timeout '%s'\n", v);
                return CLI_USAGE;
            }
            ctx.timeout_ms = (int)u;
        } else {
            fprintf(stderr, "seamtex: unknown option %s\n%s", a, USAGE);
            return CLI_USAGE;
        }
    }
    static char seed_host[256];   /* --cluster: commands without a set go to the first seed */
    unsigned seed_port = 0;
    if (ctx.cluster_seeds) {
        char first[300];
        int rc = cli_cluster_first_seed(&ctx, first, sizeof first);
        if (rc != CLI_OK)
            return rc;
        char *comma = strchr(first, ',');
        if (comma)
            *comma = 0;
        if (stp_split_addr(first, seed_host, sizeof seed_host, &seed_port) != 0) {
            fprintf(stderr, "seamtex: --cluster wants HOST:PORT[,HOST:PORT...], not '%s'\n",
                    ctx.cluster_seeds);
            return CLI_USAGE;
        }
        ctx.host = seed_host;
        ctx.port = seed_port;
        ctx.bad_env_port = NULL;
    }
    int rc = i >= argc ? repl(&ctx) : dispatch(&ctx, argc - i, argv + i);
    if (!ctx.conn_borrowed)
        stc_close(ctx.conn);
    stc_cluster_close(ctx.cluster);
    return flushed(rc);
}
