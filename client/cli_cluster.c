/* client/cli_cluster.c - the CLI's cluster side: `seamtex cluster` (nodes, sets per node,
 * under-replicated sets; text or --json), `ls` under --cluster (every node's LIST, each set
 * once) and routing of set commands under --cluster (the connection goes to a node that
 * serves the set, found by stc_cluster's rules, or for upload and delete to the set's first
 * reachable owner).
 * Does not own: the routing rules (client/libcluster.c), the JSON writer (cli_json.c), the
 * other commands.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "seamtex_cluster.h"
#include "seamtex_etcd.h"

/* The cluster handle, opened once. NULL after printing why, with *code the exit code: 1 when a
 * seed answered and refused (a daemon not in a cluster answers CLUSTER with UNSUPPORTED), 3
 * when none could be reached. */
static stc_cluster *open_cluster(cli_ctx *ctx, int *code)
{
    if (ctx->cluster)
        return ctx->cluster;
    if (!ctx->cluster_seeds && (*code = cli_check_env_port(ctx)) != CLI_OK)
        return NULL;
    char seeds[300];
    if (ctx->cluster_seeds)
        snprintf(seeds, sizeof seeds, "%s", ctx->cluster_seeds);
    else
        snprintf(seeds, sizeof seeds, "%s:%u", ctx->host, ctx->port);
    stc_opts o;
    cli_conn_opts(ctx, &o);
    int err = 0;
    char msg[512] = "";
    ctx->cluster = stc_cluster_open_url(seeds, &o, &err, msg, sizeof msg);
    if (!ctx->cluster) {
        if (stc_is_server_error(err) && msg[0])   /* the server's "OPCODE: STATUS: text" */
            fprintf(stderr, "%s: cluster %s: %s\n", ctx->prog, seeds, msg);
        else
            fprintf(stderr, "%s: cluster %s: %s: %s\n", ctx->prog, seeds, stc_strerror(err), msg);
        *code = stc_is_server_error(err) ? CLI_SERVER : CLI_CONNECT;
    }
    return ctx->cluster;
}

int cli_cluster_first_seed(cli_ctx *ctx, char *out, size_t cap)
{
    if (strncmp(ctx->cluster_seeds, "etcd://", 7)) {
        snprintf(out, cap, "%s", ctx->cluster_seeds);
        return CLI_OK;
    }
    int code = CLI_CONNECT;
    stc_cluster *cl = open_cluster(ctx, &code);
    const stc_cluster_node *nodes;
    if (!cl || stc_cluster_nodes(cl, &nodes) == 0)
        return code;
    snprintf(out, cap, "%s", nodes[0].addr);
    return CLI_OK;
}

static int probe_info(stc_conn *c, void *set)
{
    stc_info in;
    return stc_info_get(c, set, 0, 0, &in);
}

int cli_connect_routed(cli_ctx *ctx, const char *set)
{
    int code = CLI_CONNECT;
    stc_cluster *cl = open_cluster(ctx, &code);
    if (!cl)
        return code;
    if (ctx->route_held) {
        /* a command that reads the set goes to a node that serves it: an INFO routed by the
         * cluster client's rules (an owner that lacks its copy answers MOVED: followed;
         * NOT_FOUND from one owner is not final). Otherwise, the first reachable owner, whose
         * answer the command reports. */
        stc_conn *used = NULL;
        if (stc_cluster_call(cl, set, probe_info, (void *)set, &used) == 0 && used) {
            ctx->conn = used;
            ctx->conn_borrowed = 1;
            return CLI_OK;
        }
    }
    size_t order[256];
    size_t n = stc_cluster_rank(cl, set, order, 256);
    for (size_t r = 0; r < n; r++) {
        int err = 0;
        stc_conn *c = stc_cluster_conn(cl, order[r], &err);
        if (c) {
            ctx->conn = c;
            ctx->conn_borrowed = 1;   /* owned by the cluster handle */
            return CLI_OK;
        }
    }
    fprintf(stderr, "%s: no node of the cluster answers: %s\n", ctx->prog, stc_cluster_errmsg(cl));
    return CLI_CONNECT;
}

typedef struct listed {
    stc_set_entry e;
    char          name[256];
} listed;

static int cmp_listed(const void *a, const void *b)
{
    return strcmp(((const listed *)a)->name, ((const listed *)b)->name);
}

int cli_cluster_list(cli_ctx *ctx, stc_set_entry **out, size_t *nout, void **keep)
{
    *out = NULL;
    *nout = 0;
    *keep = NULL;
    int code = CLI_CONNECT;
    stc_cluster *cl = open_cluster(ctx, &code);
    if (!cl)
        return code;
    const stc_cluster_node *nodes;
    size_t nn = stc_cluster_nodes(cl, &nodes), nl = 0, cap = 0;
    listed *l = NULL;
    int rc = CLI_OK;
    for (size_t i = 0; i < nn; i++) {
        int err = 0;
        stc_conn *c = stc_cluster_conn(cl, i, &err);
        const stc_set_entry *sets = NULL;
        size_t n = 0;
        int e = c ? stc_list(c, &sets, &n) : err;
        if (e) {
            fprintf(stderr, "%s: ls: node %s at %s: %s: its sets may be missing below\n",
                    ctx->prog, nodes[i].id, nodes[i].addr, c ? stc_errmsg(c) : stc_strerror(e));
            rc = stc_is_server_error(e) ? CLI_SERVER : CLI_CONNECT;
            continue;
        }
        for (size_t k = 0; k < n; k++) {
            if (nl == cap) {
                cap = cap ? 2 * cap : 64;
                listed *g = realloc(l, cap * sizeof *l);
                if (!g) {
                    free(l);
                    fprintf(stderr, "%s: ls: out of memory\n", ctx->prog);
                    return CLI_SERVER;
                }
                l = g;
            }
            l[nl].e = sets[k];
            snprintf(l[nl].name, sizeof l[nl].name, "%s", sets[k].name);
            nl++;
        }
    }
    if (nl)
        qsort(l, nl, sizeof *l, cmp_listed);
    stc_set_entry *o = malloc((nl ? nl : 1) * sizeof *o);
    if (!o) {
        free(l);
        fprintf(stderr, "%s: ls: out of memory\n", ctx->prog);
        return CLI_SERVER;
    }
    size_t n = 0;
    for (size_t i = 0; i < nl; i++)   /* each set once: the copies of a set are the same set */
        if (!n || strcmp(o[n - 1].name, l[i].name)) {
            o[n] = l[i].e;
            o[n++].name = l[i].name;
        }
    *out = o;
    *nout = n;
    *keep = l;
    return rc;
}

typedef struct holding {
    char name[256];
    int  holders;
} holding;

static int cmp_holding(const void *a, const void *b)
{
    return strcmp(((const holding *)a)->name, ((const holding *)b)->name);
}

int cli_cmd_cluster(cli_ctx *ctx, int argc, char **argv)
{
    int json = 0;
    for (int i = 1; i < argc; i++) {
        if (cli_is_help(argv[i])) {
            printf("usage: seamtex [--cluster HOST:PORT,...] cluster [--json]\n"
                   "  the cluster's nodes (from CLUSTER), the sets each holds (LIST), and the sets\n"
                   "  with fewer copies than the cluster's replicas\n");
            return CLI_OK;
        }
        if (!strcmp(argv[i], "--json")) {
            json = 1;
        } else {
            fprintf(stderr, "seamtex cluster: unexpected '%s'\n", argv[i]);
            return CLI_USAGE;
        }
    }
    int code = CLI_CONNECT;
    stc_cluster *cl = open_cluster(ctx, &code);
    if (!cl)
        return code;
    const stc_cluster_node *nodes;
    size_t nn = stc_cluster_nodes(cl, &nodes);
    unsigned R = stc_cluster_replicas(cl);
    holding *hs = NULL;
    size_t nh = 0, caph = 0;
    int *nsets = calloc(nn ? nn : 1, sizeof *nsets), *up = calloc(nn ? nn : 1, sizeof *up);
    if (!nsets || !up) {
        free(nsets);
        free(up);
        return CLI_SERVER;
    }
    cli_json out;
    cli_json_begin(&out, stdout);   /* writes nothing: used only with --json */
    if (json) {
        cli_json_object(&out, NULL);
        cli_json_u64(&out, "replicas", R);
        cli_json_array(&out, "nodes");
    } else
        printf("%-16s %-24s %6s  %s\n", "NODE", "ADDRESS", "SETS", "STATE");
    for (size_t i = 0; i < nn; i++) {
        int err = 0;
        stc_conn *c = stc_cluster_conn(cl, i, &err);
        const stc_set_entry *sets = NULL;
        size_t n = 0;
        up[i] = c && stc_list(c, &sets, &n) == 0;
        for (size_t k = 0; up[i] && k < n; k++) {
            size_t j = 0;
            while (j < nh && strcmp(hs[j].name, sets[k].name))
                j++;
            if (j == nh) {
                if (nh == caph) {
                    caph = caph ? caph * 2 : 64;
                    holding *g = realloc(hs, caph * sizeof *hs);
                    if (!g)
                        break;
                    hs = g;
                }
                snprintf(hs[nh].name, sizeof hs[nh].name, "%s", sets[k].name);
                hs[nh++].holders = 0;
            }
            hs[j].holders++;
        }
        nsets[i] = up[i] ? (int)n : -1;
        if (json) {
            cli_json_object(&out, NULL);
            cli_json_str(&out, "id", nodes[i].id);
            cli_json_str(&out, "addr", nodes[i].addr);
            cli_json_bool(&out, "up", up[i]);
            cli_json_i64(&out, "sets", nsets[i]);
            cli_json_close(&out);
        } else {
            printf("%-16s %-24s %6d  %s\n", nodes[i].id, nodes[i].addr, nsets[i],
                   up[i] ? "up" : "unreachable");
        }
    }
    size_t want = R < nn ? R : nn;
    if (nh)
        qsort(hs, nh, sizeof *hs, cmp_holding);
    if (json) {
        cli_json_close(&out);
        cli_json_u64(&out, "sets", nh);
        cli_json_array(&out, "under_replicated");
    } else {
        printf("%zu set(s), replicas %u\n", nh, R);
    }
    size_t under = 0;
    for (size_t j = 0; j < nh; j++)
        if ((size_t)hs[j].holders < want) {
            if (json) {
                cli_json_object(&out, NULL);
                cli_json_str(&out, "name", hs[j].name);
                cli_json_i64(&out, "copies", hs[j].holders);
                cli_json_close(&out);
            } else {
                printf("under-replicated: %s (%d of %zu copies)\n", hs[j].name, hs[j].holders, want);
            }
            under++;
        }
    int rc = CLI_OK;
    if (json) {
        cli_json_close(&out);
        cli_json_close(&out);
        rc = cli_json_finish(&out);
    } else if (!under) {
        printf("no under-replicated sets\n");
    }
    free(hs);
    free(nsets);
    free(up);
    return rc;
}
