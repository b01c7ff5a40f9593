/* server/config.h - seamtexd's settings: defaults, the config file, command-line flags, --help.
 *
 * Owns: the list of settings (one table: flag name == config key, type, default, help), parsing
 * of both sources (the file first, then flags override it), size suffixes (K, M, G), and the
 * diff logged on SIGHUP. Does not own: applying settings to a running server (server.c).
 *
 * Config file: one "key = value" per line, '#' starts a comment, blank lines ignored. Keys are
 * the long flag names without "--" (listen, data-dir, max-conns, ...). Boolean flags take
 * yes/no/true/false/1/0 in the file.
 */
#ifndef STS_CONFIG_H
#define STS_CONFIG_H

#include <stddef.h>
#include <stdint.h>

#define STS_DEFAULT_PORT 7450
#define STS_TOKEN_MAX 255
#define STS_VERSION "0.1"   /* --version, the build-info metric */

typedef struct sts_config {
    char     listen[128];       /* host:port or unix:PATH; default 127.0.0.1:7450 */
    char     data_dir[1024];    /* "" = no persistence (sets live in memory only) */
    char     token[STS_TOKEN_MAX + 1];  /* "" = no token */
    char     token_file[1024];  /* read at start and on SIGHUP; overrides token */
    char     port_file[1024];   /* written with the bound port once serving */
    char     config_file[1024]; /* where the settings came from, "" = none */
    uint32_t max_conns;         /* connections at once; more are refused with BUSY */
    uint32_t idle_timeout;      /* seconds without traffic before a connection is closed; 0 = never */
    uint32_t request_timeout;   /* seconds a request frame may take from its first byte to its
                                   last (plus its body at request_min_rate); 0 = no deadline */
    uint64_t request_min_rate;  /* bytes/s a request body must at least arrive at */
    uint64_t max_frame;         /* largest request body accepted (bytes) */
    uint64_t max_upload;        /* largest uploaded file (bytes) */
    uint32_t deadline_ms;       /* server-side deadline per request (0 = none) */
    uint32_t io_threads;        /* event-loop threads */
    int      pin_io;            /* pin I/O thread i to the i-th CPU the process may run on */
    uint32_t workers;           /* worker threads for heavy requests */
    uint32_t max_batch;         /* queries per SAMPLE request */
    uint32_t heavy_batch;       /* SAMPLE batches above this go to a worker */
    uint32_t split_batch;       /* SAMPLE batches of this many queries or more are split with
                                   idle workers (0 = never) */
    uint64_t conn_out_cap;      /* pending reply bytes per connection before reading pauses */
    uint64_t max_memory;        /* all connection buffers and open fetches together (bytes) */
    uint64_t conn_fetch_cap;    /* bytes of open fetches per connection */
    uint32_t max_sets;          /* names in the registry */
    uint32_t max_uploads;       /* unfinished uploads at once (kept ones included) */
    uint32_t upload_keep;       /* seconds an unfinished upload outlives its connection */
    uint32_t max_jobs;          /* queued + running COMPRESS jobs */
    uint32_t job_threads;       /* encoder threads of one job, 0 = one per core */
    uint64_t max_set_bytes;     /* texel arena of one imported set */
    uint64_t memory_budget;     /* resident texture bytes before cold sets are released
                                   (0 = unlimited) */
    int      native;            /* write and map native files (default 1) */
    int      verify_native;     /* check native files' texel CRCs at start */
    int      default_set;       /* load the built-in set as "default" */
    int      log_level;         /* sts_level */
    int      log_format;        /* sts_log_format: text or json (restart only) */
    char     metrics_listen[128]; /* HOST:PORT or PORT (127.0.0.1) for GET /metrics; "" = off */
    char     unix_mode[8];      /* octal file mode of a unix:PATH socket; default "0600" */
    uint64_t shm_max;           /* largest shared-memory region a Unix client may attach
                                   (bytes; 0 = shared memory off; shm.c) */
    /* cluster (docs/cluster.md; none of it is reloadable) */
    char     cluster[1024];     /* etcd://HOST:PORT[,HOST:PORT...]/PREFIX, "" = no cluster */
    char     node_id[65];       /* this node's id in the cluster */
    char     advertise[256];    /* HOST:PORT other nodes and clients dial */
    uint32_t replicas;          /* copies of each set (R) */
    uint32_t write_quorum;      /* owners durable before an upload is acknowledged (W); 0 = R */
    uint32_t lease_ttl;         /* seconds the membership lease outlives a dead node */
    uint32_t repair_interval;   /* seconds between repair passes */
} sts_config;

/* Fills the defaults. */
void sts_config_defaults(sts_config *c);

/* Parses argv: a --config FILE is read first (wherever it appears), then every other flag
 * overrides. Returns 0 to run, 1 when --help / --version printed and the program should exit
 * 0, -1 on an error (message written to err). */
int sts_config_from_args(sts_config *c, int argc, char **argv, char *err, size_t errcap);

/* Reads a config file into c (keys override what c holds). 0 or -1 with a message naming the
 * file and line. */
int sts_config_read_file(sts_config *c, const char *path, char *err, size_t errcap);

/* The parser of sts_config_read_file on len bytes in memory (name is used in messages; the
 * file reader adds the 1 MiB file cap and sets config_file). A line over 2047 bytes or a NUL
 * byte is an error. */
int sts_config_read_mem(sts_config *c, const char *buf, size_t len, const char *name, char *err,
                        size_t errcap);

/* Reads token_file into token when set. 0 or -1. */
int sts_config_load_token(sts_config *c, char *err, size_t errcap);

/* Checks values against each other (threads >= 1, ...). 0 or -1. */
int sts_config_check(const sts_config *c, char *err, size_t errcap);

/* Writes the --help text to f. */
void sts_config_help(void *file);

/* Writes "key: old -> new" for each reloadable setting that differs into out (one line each,
 * the token shown as "(changed)"); returns the number of differences. */
int sts_config_diff(const sts_config *a, const sts_config *b, char *out, size_t cap);

/* Splits "host:port" ("[v6]:port" too). 0 or -1. */
int sts_parse_listen(const char *s, char *host, size_t hostcap, int *port);
/* --metrics-listen: "HOST:PORT" as sts_parse_listen, or a bare "PORT" meaning 127.0.0.1. */
int sts_metrics_addr(const char *s, char *host, size_t hostcap, int *port);

#endif
