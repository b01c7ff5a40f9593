/* client/cli.h - internal header of the command-line client `seamtex` (not installed).
 *
 * Owns: what the command files share: the global options, the connection, exit codes, the
 * progress bar. seamtex_cli.c has main, dispatch and the small commands (ping, ls, info,
 * stats, delete); cli_sample.c the sample command; cli_transfer.c upload, fetch, compress.
 * Does not own: the protocol or the connection logic (libseamtex, client/seamtex.h).
 */
#ifndef STC_CLI_H
#define STC_CLI_H

#include <stdint.h>
#include <stdio.h>

#include "cli_json.h"
#include "seamtex.h"

/* Exit codes. */
enum {
    CLI_OK      = 0,
    CLI_SERVER  = 1,   /* the server refused, or a local file could not be used */
    CLI_USAGE   = 2,
    CLI_CONNECT = 3    /* could not connect, or the connection broke */
};

typedef struct cli_ctx {
    const char *host;
    unsigned    port;
    const char *token;
    int         timeout_ms;
    const char *prog;          /* "seamtex" */
    stc_conn   *conn;          /* opened by cli_connect */
    const char *cluster_seeds; /* --cluster HOST:PORT,... or etcd:// URL: set commands go to
                                  an owner */
    const char *route_set;     /* the set the command names (routing under --cluster) */
    int         route_held;    /* the command reads route_set (not upload, delete): routed to
                                  a node that serves it (MOVED followed, NOT_FOUND not final) */
    struct stc_cluster *cluster;   /* opened by the first routed command (cli_cluster.c) */
    int         conn_borrowed; /* conn belongs to cluster */
    const char *bad_env_port;  /* $SEAMTEX_PORT when it is not a port and -p did not replace it */
} cli_ctx;

/* CLI_USAGE after saying so when $SEAMTEX_PORT is not a port, -p did not replace it and the
 * host is not a unix: address; else CLI_OK. */
int cli_check_env_port(const cli_ctx *ctx);
/* The connection options of every command (token, client name, --timeout for the connect,
 * HELLO and each request), for cli_connect and the cluster handle alike. */
void cli_conn_opts(const cli_ctx *ctx, stc_opts *o);
/* Opens ctx->conn; on failure prints why and returns CLI_CONNECT (cli_check_env_port's
 * CLI_USAGE first). */
int cli_connect(cli_ctx *ctx);
/* Prints "seamtex: <what>: <error>" for a failed library call and returns the exit code. */
int cli_fail(cli_ctx *ctx, const char *what, int code);
/* Parses numbers (cli_parse.c); 0 or -1. A float must be within float's range
 * ("nan" and "inf" are accepted: the server answers them with the NONFINITE status). */
int cli_parse_u32(const char *s, uint32_t *out);
int cli_parse_float(const char *s, float *out);
/* One line of a query file (cli_parse.c), changed in place: "face u v [dudx dvdx dudy dvdy]"
 * or, for cli_dir_query_line, "x y z [ddx0 ddx1 ddx2 ddy0 ddy1 ddy2]"; fields split by
 * spaces, tabs or commas, '#' starts a comment. 1 = a query in *q, 0 = a blank or comment
 * line, -1 = a bad line (q unspecified). */
int cli_query_line(char *line, stc_query *q);
int cli_dir_query_line(char *line, stc_dir_query *q);
/* 1 when argv[i] is --help or -?. */
int cli_is_help(const char *a);
/* cli_json_end, then the exit code: CLI_OK, or CLI_SERVER (with a message) when writing the
 * document failed. Every --json output ends through it. */
int cli_json_finish(cli_json *j);

/* Names of the store's enums for printing. */
const char *cli_kind_name(unsigned kind);
const char *cli_dtype_name(unsigned dtype);
/* "12.3 MiB" into buf. */
const char *cli_bytes(uint64_t n, char *buf, size_t cap);

/* Progress on stderr: a bar when stderr is a terminal, plain "what: N%" lines every 10 %
 * otherwise. */
typedef struct cli_progress {
    const char *what;
    int         tty;
    int         last;          /* last percentage printed */
    int         bytes;         /* 1: done/total are bytes (shown with a rate) */
    uint64_t    t0;            /* start, ns */
} cli_progress;
void cli_progress_init(cli_progress *p, const char *what, int bytes);
void cli_progress_update(cli_progress *p, uint64_t done, uint64_t total);
void cli_progress_end(cli_progress *p);

/* Commands: argc/argv start at the command name. Each returns an exit code. */
int cli_cmd_sample(cli_ctx *ctx, int argc, char **argv);
int cli_cmd_upload(cli_ctx *ctx, int argc, char **argv);
int cli_cmd_fetch(cli_ctx *ctx, int argc, char **argv);
int cli_cmd_compress(cli_ctx *ctx, int argc, char **argv);
int cli_cmd_cluster(cli_ctx *ctx, int argc, char **argv);
/* `ls` under --cluster: the sets of every node (LIST), each once, sorted by name, in *sets (n
 * entries; free *sets and *keep, which holds the names). CLI_OK, or the code of a node that
 * did not answer (said on stderr; the list holds the other nodes' sets). */
int cli_cluster_list(cli_ctx *ctx, stc_set_entry **sets, size_t *n, void **keep);
/* --cluster: points ctx->conn at the first reachable node of set's ranking (cli_cluster.c). */
int cli_connect_routed(cli_ctx *ctx, const char *set);
/* --cluster: the seed list (HOST:PORT,...) into out, or for an etcd:// URL the address of the
 * first node of the cluster opened from it (cli_cluster.c). CLI_OK or CLI_CONNECT (printed). */
int cli_cluster_first_seed(cli_ctx *ctx, char *out, size_t cap);

#endif
