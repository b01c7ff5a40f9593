/* server/config.c - settings table, config file, flags, --help (see config.h). */
#include "config.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "log.h"
#include "unixaddr.h"

enum { T_STR, T_U32, T_SIZE, T_BOOL, T_LEVEL, T_NOT, T_LOGFMT };

typedef struct opt {
    const char *name;      /* flag without "--", config key */
    int         type;
    size_t      off;       /* offset in sts_config */
    size_t      cap;       /* strings: buffer size */
    int         reload;    /* applied on SIGHUP */
    const char *arg;       /* placeholder in --help */
    const char *help;
} opt;

#define O(f) offsetof(sts_config, f)
#define S(f) sizeof(((sts_config *)0)->f)
static const opt OPTS[] = {
    {"listen", T_STR, O(listen), S(listen), 0, "HOST:PORT|unix:PATH",
     "address to serve on (default 127.0.0.1:7450; port 0 picks a free port); unix:PATH\n"
     "serves same-host clients on a Unix socket, its file mode from unix-mode"},
    {"data-dir", T_STR, O(data_dir), S(data_dir), 0, "DIR",
     "durable set store; every acknowledged upload is on disk there (default: none,\n"
     "sets live in memory only and vanish at exit)"},
    {"token", T_STR, O(token), S(token), 1, "SECRET",
     "shared token required for uploads, deletes, compress jobs and job cancels;\n"
     "reads stay open (default: none)"},
    {"token-file", T_STR, O(token_file), S(token_file), 1, "FILE",
     "read the token from FILE (first line) instead of the command line"},
    {"port-file", T_STR, O(port_file), S(port_file), 0, "FILE",
     "write the bound port to FILE once ready (useful with port 0)"},
    {"max-conns", T_U32, O(max_conns), 0, 1, "N",
     "connections at once; the next one gets a BUSY reply and is closed (default 10000)"},
    {"idle-timeout", T_U32, O(idle_timeout), 0, 1, "SECONDS",
     "close a connection silent this long; 0 = never (default 300)"},
    {"request-timeout", T_U32, O(request_timeout), 0, 1, "SECONDS",
     "a request frame must arrive whole within SECONDS of its first byte, plus its body's\n"
     "size at request-min-rate; else the connection is closed; 0 = no deadline (default 5)"},
    {"request-min-rate", T_SIZE, O(request_min_rate), 0, 1, "BYTES",
     "the slowest rate, per second, a request body may arrive at (default 128K: a 4 MiB\n"
     "chunk may take request-timeout + 32 s; past request-timeout, what has arrived must\n"
     "keep up with it)"},
    {"max-frame", T_SIZE, O(max_frame), 0, 1, "BYTES",
     "largest request body; larger ones get TOO_LARGE and are skipped (default 64M)"},
    {"max-upload", T_SIZE, O(max_upload), 0, 1, "BYTES",
     "largest uploaded file (default 1G)"},
    {"deadline-ms", T_U32, O(deadline_ms), 0, 1, "MS",
     "a request still waiting for a worker after MS gets TIMEOUT; 0 = none (default 10000)"},
    {"io-threads", T_U32, O(io_threads), 0, 0, "N", "event-loop threads (default 2)"},
    {"pin-io", T_BOOL, O(pin_io), 0, 0, "yes|no",
     "pin I/O thread i to the i-th CPU the daemon may run on, wrapping around (STATS\n"
     "io<i>_cpu); workers stay unpinned (default no)"},
    {"workers", T_U32, O(workers), 0, 0, "N",
     "worker threads for heavy requests: big SAMPLE batches, upload commits, imports (default 2)"},
    {"max-batch", T_U32, O(max_batch), 0, 1, "N", "queries per SAMPLE request (default 1048576)"},
    {"heavy-batch", T_U32, O(heavy_batch), 0, 1, "N",
     "SAMPLE batches whose body, queries counted as 28 bytes, is over N x 28 bytes (name\n"
     "and parameters included: from N - 1 queries with a short name) run on a worker\n"
     "(default 16384)"},
    {"split-batch", T_U32, O(split_batch), 0, 1, "N",
     "SAMPLE batches of N queries or more are sampled in parts by the thread that has them and "
     "idle workers together; 0 = never (default 2048)"},
    {"conn-out-cap", T_SIZE, O(conn_out_cap), 0, 1, "BYTES",
     "unsent reply bytes per connection before the server stops reading it (default 4M)"},
    {"max-memory", T_SIZE, O(max_memory), 0, 1, "BYTES",
     "all connection buffers and open fetches together; a request that would pass it gets\n"
     "BUSY (default 1G)"},
    {"conn-fetch-cap", T_SIZE, O(conn_fetch_cap), 0, 1, "BYTES",
     "bytes of open fetches per connection; past it FETCH_OPEN gets BUSY, a file larger\n"
     "than it TOO_LARGE (default 1G)"},
    {"max-sets", T_U32, O(max_sets), 0, 1, "N", "sets held at once (default 10000)"},
    {"max-uploads", T_U32, O(max_uploads), 0, 1, "N",
     "unfinished uploads at once, kept ones included (default 64)"},
    {"upload-keep", T_U32, O(upload_keep), 0, 1, "SECONDS",
     "keep an unfinished upload this long after its connection drops, for UPLOAD_BEGIN with\n"
     "RESUME; 0 = drop it at once (default 600)"},
    {"max-jobs", T_U32, O(max_jobs), 0, 1, "N", "queued or running compress jobs (default 16)"},
    {"job-threads", T_U32, O(job_threads), 0, 1, "N",
     "threads one compress job encodes with; 0 = one per core (default 1: jobs leave the\n"
     "other cores to the requests)"},
    {"max-set-bytes", T_SIZE, O(max_set_bytes), 0, 1, "BYTES",
     "texel memory of one imported set, and its mesh's at 128 bytes a triangle (default 8G)"},
    {"memory-budget", T_SIZE, O(memory_budget), 0, 1, "BYTES",
     "texture memory kept resident (pages of native files mapped in seamtexd, plus built\n"
     "Ptex tables); the least recently sampled sets are released past it and fault back in\n"
     "(from the page cache) when sampled; 0 = unlimited (default 0)"},
    {"native", T_BOOL, O(native), 0, 0, "yes|no",
     "keep a native file (mapped, no import at start) beside every set's source (default yes;\n"
     "no: every start re-imports every source, as before native files)"},
    {"verify-native", T_BOOL, O(verify_native), 0, 0, "yes|no",
     "at start also check every native file's texel CRC and every source's CRC-32 (reads\n"
     "every byte; default no: headers, tables, small sections and source sizes are checked)"},
    {"default-set", T_BOOL, O(default_set), 0, 0, "yes|no",
     "load the built-in set as \"default\" at start (default yes)"},
    {"no-default-set", T_NOT, O(default_set), 0, 0, NULL, "same as --default-set no"},
    {"unix-mode", T_STR, O(unix_mode), S(unix_mode), 0, "OCTAL",
     "file mode of a unix:PATH socket: who may connect (default 0600: the daemon's user)"},
    {"shm-max", T_SIZE, O(shm_max), 0, 1, "BYTES",
     "largest shared-memory region a client on a Unix socket may attach for sampling\n"
     "(SHM_ATTACH, PROTOCOL.md 4.12); 0 = off (default 256M)"},
    {"log-level", T_LEVEL, O(log_level), 0, 1, "LEVEL", "error, warn, info or debug (default info)"},
    {"log-format", T_LOGFMT, O(log_format), 0, 0, "text|json",
     "text lines, or one JSON object per line with time, level, message and the line's\n"
     "fields (default text)"},
    {"metrics-listen", T_STR, O(metrics_listen), S(metrics_listen), 0, "HOST:PORT",
     "serve GET /metrics (Prometheus text format) on HOST:PORT; a bare PORT means\n"
     "127.0.0.1:PORT (default: off)"},
    {"cluster", T_STR, O(cluster), S(cluster), 0, "etcd://HOST:PORT[,HOST:PORT...]/PREFIX",
     "join the cluster kept in etcd under PREFIX (docs/cluster.md); needs --data-dir,\n"
     "--node-id and --advertise (default: no cluster)"},
    {"node-id", T_STR, O(node_id), S(node_id), 0, "ID",
     "this node's id in the cluster: 1..64 bytes of [A-Za-z0-9._-], stable across restarts"},
    {"advertise", T_STR, O(advertise), S(advertise), 0, "HOST:PORT",
     "the address other nodes and clients reach this node at"},
    {"replicas", T_U32, O(replicas), 0, 0, "R", "copies of each set in the cluster (default 2)"},
    {"write-quorum", T_U32, O(write_quorum), 0, 0, "W",
     "owners that must hold an upload durably before it is acknowledged, 1..R (default R)"},
    {"lease-ttl", T_U32, O(lease_ttl), 0, 0, "SECONDS",
     "the membership lease: a node that stops renewing it leaves after SECONDS (default 5)"},
    {"repair-interval", T_U32, O(repair_interval), 0, 0, "SECONDS",
     "seconds between repair passes (also run at start and on every membership change;\n"
     "default 5)"},
};
#define NOPTS (sizeof OPTS / sizeof OPTS[0])

void sts_config_defaults(sts_config *c)
{
    memset(c, 0, sizeof *c);
    snprintf(c->listen, sizeof c->listen, "127.0.0.1:%d", STS_DEFAULT_PORT);
    c->max_conns = 10000;
    c->upload_keep = 600;
    c->idle_timeout = 300;
    c->request_timeout = 5;
    c->request_min_rate = 128u << 10;
    c->conn_fetch_cap = 1u << 30;
    c->max_frame = 64u << 20;
    c->max_upload = 1u << 30;
    c->deadline_ms = 10000;
    c->io_threads = 2;
    snprintf(c->unix_mode, sizeof c->unix_mode, "0600");
    c->workers = 2;
    c->max_batch = 1u << 20;
    c->heavy_batch = 16384;
    c->split_batch = 2048;
    c->shm_max = 256u << 20;
    c->conn_out_cap = 4u << 20;
    c->max_memory = 1u << 30;
    c->max_sets = 10000;
    c->max_uploads = 64;
    c->max_jobs = 16;
    c->job_threads = 1;
    c->max_set_bytes = (uint64_t)8 << 30;
    c->default_set = 1;
    c->native = 1;
    c->log_level = STS_INFO;
    c->replicas = 2;
    c->lease_ttl = 5;
    c->repair_interval = 5;
}

static const opt *find_opt(const char *name, size_t len)
{
    for (size_t i = 0; i < NOPTS; i++)
        if (strlen(OPTS[i].name) == len && !strncmp(OPTS[i].name, name, len))
            return &OPTS[i];
    return NULL;
}

static int parse_size(const char *s, uint64_t *out)
{
    char *end;
    errno = 0;
    if (!isdigit((unsigned char)*s))
        return -1;
    unsigned long long v = strtoull(s, &end, 10);
    if (errno)
        return -1;
    uint64_t mul = 1;
    switch (*end) {
    case 'k': case 'K': mul = 1ull << 10; end++; break;
    case 'm': case 'M': mul = 1ull << 20; end++; break;
    case 'g': case 'G': mul = 1ull << 30; end++; break;
    default: break;
    }
    if (*end == 'i' || *end == 'B')
        end++;
    if (*end == 'B')
        end++;
    if (*end)
        return -1;
    if (v > UINT64_MAX / mul)
        return -1;
    *out = v * mul;
    return 0;
}

static int parse_bool(const char *s, int *out)
{
    if (!strcmp(s, "yes") || !strcmp(s, "true") || !strcmp(s, "1") || !strcmp(s, "on")) {
        *out = 1;
        return 0;
    }
    if (!strcmp(s, "no") || !strcmp(s, "false") || !strcmp(s, "0") || !strcmp(s, "off")) {
        *out = 0;
        return 0;
    }
    return -1;
}

/* Sets one option from its text value; val may be NULL only for T_NOT. */
static int set_opt(sts_config *c, const opt *o, const char *val, char *err, size_t errcap)
{
    char *base = (char *)c + o->off;
    switch (o->type) {
    case T_STR:
        if (strlen(val) >= o->cap) {
            snprintf(err, errcap, "%s: value is longer than %zu bytes", o->name, o->cap - 1);
            return -1;
        }
        memcpy(base, val, strlen(val) + 1);
        return 0;
    case T_U32: {
        uint64_t v;
        if (parse_size(val, &v) || v > UINT32_MAX) {
            snprintf(err, errcap, "%s: '%s' is not a number (0..4294967295)", o->name, val);
            return -1;
        }
        *(uint32_t *)(void *)base = (uint32_t)v;
        return 0;
    }
    case T_SIZE: {
        uint64_t v;
        if (parse_size(val, &v)) {
            snprintf(err, errcap, "%s: '%s' is not a size (e.g. 4096, 64K, 16M, 1G)", o->name, val);
            return -1;
        }
        *(uint64_t *)(void *)base = v;
        return 0;
    }
    case T_BOOL: {
        int b;
        if (parse_bool(val, &b)) {
            snprintf(err, errcap, "%s: '%s' is not yes or no", o->name, val);
            return -1;
        }
        *(int *)(void *)base = b;
        return 0;
    }
    case T_NOT:
        *(int *)(void *)base = 0;
        return 0;
    case T_LOGFMT: {
        int l = sts_log_format_parse(val);
        if (l < 0) {
            snprintf(err, errcap, "%s: '%s' is not text or json", o->name, val);
            return -1;
        }
        *(int *)(void *)base = l;
        return 0;
    }
    case T_LEVEL: {
        int l = sts_level_parse(val);
        if (l < 0) {
            snprintf(err, errcap, "%s: '%s' is not one of error, warn, info, debug", o->name, val);
            return -1;
        }
        *(int *)(void *)base = l;
        return 0;
    }
    }
    return -1;
}

static char *trim(char *s)
{
    while (isspace((unsigned char)*s))
        s++;
    size_t n = strlen(s);
    while (n && isspace((unsigned char)s[n - 1]))
        s[--n] = 0;
    return s;
}

/* The longest line of a config file, its newline included. */
#define LINE_MAX_BYTES 2048
/* The largest config file read (a few hundred bytes are usual). */
#define FILE_MAX_BYTES (1u << 20)

int sts_config_read_mem(sts_config *c, const char *buf, size_t len, const char *name, char *err,
                        size_t errcap)
{
    char line[LINE_MAX_BYTES];
    int ln = 0;
    size_t pos = 0;
    while (pos < len) {
        ln++;
        const char *nl = memchr(buf + pos, '\n', len - pos);
        size_t n = nl ? (size_t)(nl - (buf + pos)) : len - pos;
        if (n >= sizeof line) {
            snprintf(err, errcap, "%s:%d: line longer than %d bytes", name, ln, LINE_MAX_BYTES - 1);
            return -1;
        }
        if (memchr(buf + pos, '\0', n)) {
            snprintf(err, errcap, "%s:%d: a NUL byte (not a text file)", name, ln);
            return -1;
        }
        memcpy(line, buf + pos, n);
        line[n] = 0;
        pos += n + (nl != NULL);
        char *hash = strchr(line, '#');
        if (hash)
            *hash = 0;
        char *s = trim(line);
        if (!*s)
            continue;
        char *eq = strchr(s, '=');
        if (!eq) {
            snprintf(err, errcap, "%s:%d: expected 'key = value'", name, ln);
            return -1;
        }
        *eq = 0;
        char *key = trim(s), *val = trim(eq + 1);
        const opt *o = find_opt(key, strlen(key));
        if (!o || o->type == T_NOT) {
            snprintf(err, errcap, "%s:%d: unknown key '%.64s' (see seamtexd --help)", name, ln, key);
            return -1;
        }
        char e2[256];
        if (set_opt(c, o, val, e2, sizeof e2)) {
            snprintf(err, errcap, "%s:%d: %s", name, ln, e2);
            return -1;
        }
    }
    return 0;
}

int sts_config_read_file(sts_config *c, const char *path, char *err, size_t errcap)
{
    FILE *f = fopen(path, "re");
    if (!f) {
        snprintf(err, errcap, "config %s: %s", path, strerror(errno));
        return -1;
    }
    char *buf = malloc(FILE_MAX_BYTES + 1);
    if (!buf) {
        fclose(f);
        snprintf(err, errcap, "config %s: out of memory", path);
        return -1;
    }
    size_t len = fread(buf, 1, FILE_MAX_BYTES + 1, f);
    int bad = ferror(f);
    fclose(f);
    int rc = -1;
    if (bad)
        snprintf(err, errcap, "config %s: read error", path);
    else if (len > FILE_MAX_BYTES)
        snprintf(err, errcap, "config %s: larger than %u bytes", path, FILE_MAX_BYTES);
    else
        rc = sts_config_read_mem(c, buf, len, path, err, errcap);
    free(buf);
    if (rc == 0)
        snprintf(c->config_file, sizeof c->config_file, "%s", path);
    return rc;
}

int sts_config_load_token(sts_config *c, char *err, size_t errcap)
{
    if (!c->token_file[0])
        return 0;
    FILE *f = fopen(c->token_file, "re");
    if (!f) {
        snprintf(err, errcap, "token-file %s: %s", c->token_file, strerror(errno));
        return -1;
    }
    char line[STS_TOKEN_MAX + 2];
    if (!fgets(line, sizeof line, f))
        line[0] = 0;
    fclose(f);
    char *t = trim(line);
    if (!*t) {
        snprintf(err, errcap, "token-file %s is empty", c->token_file);
        return -1;
    }
    snprintf(c->token, sizeof c->token, "%s", t);
    return 0;
}

int sts_config_from_args(sts_config *c, int argc, char **argv, char *err, size_t errcap)
{
    /* the config file first, so flags override it */
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--config") || !strcmp(a, "-c")) {
            if (i + 1 >= argc) {
                snprintf(err, errcap, "--config needs a file");
                return -1;
            }
            if (sts_config_read_file(c, argv[i + 1], err, errcap))
                return -1;
            i++;
        } else if (!strncmp(a, "--config=", 9)) {
            if (sts_config_read_file(c, a + 9, err, errcap))
                return -1;
        }
    }
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            sts_config_help(stdout);
            return 1;
        }
        if (!strcmp(a, "--version")) {
            printf("seamtexd " STS_VERSION " (protocol version 1)\n");
            return 1;
        }
        if (!strcmp(a, "--config") || !strcmp(a, "-c")) {
            i++;
            continue;
        }
        if (!strncmp(a, "--config=", 9))
            continue;
        if (strncmp(a, "--", 2) != 0) {
            snprintf(err, errcap, "unexpected argument '%s' (see seamtexd --help)", a);
            return -1;
        }
        const char *name = a + 2, *eq = strchr(name, '=');
        size_t len = eq ? (size_t)(eq - name) : strlen(name);
        const opt *o = find_opt(name, len);
        if (!o) {
            snprintf(err, errcap, "unknown flag '%s' (see seamtexd --help)", a);
            return -1;
        }
        const char *val = NULL;
        if (o->type == T_NOT) {
            if (eq) {
                snprintf(err, errcap, "--%s takes no value", o->name);
                return -1;
            }
        } else if (eq) {
            val = eq + 1;
        } else if (o->type == T_BOOL && (i + 1 >= argc || strncmp(argv[i + 1], "--", 2) == 0)) {
            val = "yes";
        } else {
            if (i + 1 >= argc) {
                snprintf(err, errcap, "--%s needs a value (%s)", o->name, o->arg);
                return -1;
            }
            val = argv[++i];
        }
        if (set_opt(c, o, val, err, errcap))
            return -1;
    }
    return 0;
}

int sts_config_check(const sts_config *c, char *err, size_t errcap)
{
    char host[128];
    int port;
    if (stu_is_unix_addr(c->listen)) {
        struct sockaddr_un sa;
        socklen_t len;
        if (stu_unix_addr(c->listen, &sa, &len) != 0) {
            snprintf(err, errcap, "listen: '%s': %s", c->listen, errno == ENAMETOOLONG
                     ? "the path is over 107 bytes" : "unix: needs a path");
            return -1;
        }
    } else if (sts_parse_listen(c->listen, host, sizeof host, &port)) {
        snprintf(err, errcap, "listen: '%s' is not HOST:PORT", c->listen);
        return -1;
    }
    char *end;
    unsigned long mode = strtoul(c->unix_mode, &end, 8);
    if (!c->unix_mode[0] || *end || mode > 0777) {
        snprintf(err, errcap, "unix-mode must be an octal file mode, 0..0777");
        return -1;
    }
    if (c->io_threads < 1 || c->io_threads > 64) {
        snprintf(err, errcap, "io-threads must be 1..64");
        return -1;
    }
    if (c->workers < 1 || c->workers > 256) {
        snprintf(err, errcap, "workers must be 1..256");
        return -1;
    }
    if (c->max_frame < 4096 || c->max_frame > 0xFFFFFFFFu) {
        snprintf(err, errcap, "max-frame must be 4K..4G-1");
        return -1;
    }
    if (c->max_conns < 1) {
        snprintf(err, errcap, "max-conns must be at least 1");
        return -1;
    }
    if (c->max_batch < 1) {
        snprintf(err, errcap, "max-batch must be at least 1");
        return -1;
    }
    if (c->conn_out_cap < 65536) {
        snprintf(err, errcap, "conn-out-cap must be at least 64K");
        return -1;
    }
    if (c->metrics_listen[0] && sts_metrics_addr(c->metrics_listen, host, sizeof host, &port)) {
        snprintf(err, errcap, "metrics-listen: '%s' is not HOST:PORT or PORT", c->metrics_listen);
        return -1;
    }
    if (c->request_min_rate < 1024) {
        snprintf(err, errcap, "request-min-rate must be at least 1K");
        return -1;
    }
    if (c->cluster[0]) {
        if (!c->data_dir[0] || !c->node_id[0] || !c->advertise[0]) {
            snprintf(err, errcap, "cluster needs --data-dir, --node-id and --advertise");
            return -1;
        }
        if (c->replicas < 1 || c->replicas > 16 || c->write_quorum > c->replicas) {
            snprintf(err, errcap, "replicas must be 1..16 and write-quorum 1..replicas");
            return -1;
        }
        if (c->lease_ttl < 1 || c->lease_ttl > 3600 || c->repair_interval < 1) {
            snprintf(err, errcap, "lease-ttl must be 1..3600 and repair-interval at least 1");
            return -1;
        }
    }
    return 0;
}

int sts_metrics_addr(const char *s, char *host, size_t hostcap, int *port)
{
    if (*s && strspn(s, "0123456789") == strlen(s)) {   /* a bare port: loopback */
        char full[32];
        if (strlen(s) > 5)
            return -1;
        snprintf(full, sizeof full, "127.0.0.1:%s", s);
        return sts_parse_listen(full, host, hostcap, port);
    }
    return sts_parse_listen(s, host, hostcap, port);
}

int sts_parse_listen(const char *s, char *host, size_t hostcap, int *port)
{
    const char *colon;
    if (s[0] == '[') {
        const char *rb = strchr(s, ']');
        if (!rb || rb[1] != ':')
            return -1;
        if ((size_t)(rb - s - 1) >= hostcap)
            return -1;
        memcpy(host, s + 1, (size_t)(rb - s - 1));
        host[rb - s - 1] = 0;
        colon = rb + 1;
    } else {
        colon = strrchr(s, ':');
        if (!colon || (size_t)(colon - s) >= hostcap)
            return -1;
        memcpy(host, s, (size_t)(colon - s));
        host[colon - s] = 0;
    }
    char *end;
    long p = strtol(colon + 1, &end, 10);
    if (!colon[1] || *end || p < 0 || p > 65535)
        return -1;
    if (!host[0])
        snprintf(host, hostcap, "127.0.0.1");
    *port = (int)p;
    return 0;
}

void sts_config_help(void *file)
{
    FILE *f = file;
    fprintf(f,
        "seamtexd - the seamtex texture daemon: holds texture sets in memory and serves\n"
        "seam-free sampling, uploads and BC1 compression over the seamtex binary protocol\n"
        "(PROTOCOL.md). Runs in the foreground and logs to stderr.\n"
        "\n"
        "usage: seamtexd [--config FILE] [--flag VALUE]...\n"
        "\n"
        "Every flag is also a config-file key of the same name (\"max-conns = 500\").\n"
        "The file is read first; flags given on the command line override it.\n"
        "Sizes take K, M or G suffixes (powers of 1024).\n"
        "\n");
    fprintf(f, "  --config FILE\n      read settings from FILE; SIGHUP re-reads it\n");
    for (size_t i = 0; i < NOPTS; i++) {
        const opt *o = &OPTS[i];
        fprintf(f, "  --%s%s%s%s\n      ", o->name, o->arg ? " " : "", o->arg ? o->arg : "",
                o->reload ? "   [reloaded on SIGHUP]" : "");
        for (const char *p = o->help; *p; p++) {
            fputc(*p, f);
            if (*p == '\n')
                fputs("      ", f);
        }
        fputc('\n', f);
    }
    fprintf(f,
        "  --help, --version\n"
        "\n"
        "Signals: SIGTERM or SIGINT stop accepting, finish the requests in flight, flush the\n"
        "replies and exit 0. SIGHUP re-reads the config file (and token file): limits, token\n"
        "and log level change at once, the listen address and thread counts need a restart;\n"
        "what changed is logged.\n"
        "\n"
        "Security: binds 127.0.0.1 unless told otherwise. With a token, UPLOAD_*, DELETE,\n"
        "COMPRESS and JOB_CANCEL need it (HELLO carries it); reads stay open. Set names are\n"
        "1..255 bytes of A-Z a-z 0-9 . _ - not starting with '.'.\n"
        "\n"
        "Examples:\n"
        "  seamtexd --data-dir /var/lib/seamtex\n"
        "  seamtexd --listen 127.0.0.1:0 --port-file /tmp/port --no-default-set\n"
        "  seamtexd --config /etc/seamtex/seamtexd.conf --log-level debug\n");
}

static void fmt_val(const sts_config *c, const opt *o, char *out, size_t cap)
{
    const char *base = (const char *)c + o->off;
    switch (o->type) {
    case T_STR: snprintf(out, cap, "%s", base); break;
    case T_U32: snprintf(out, cap, "%u", *(const uint32_t *)(const void *)base); break;
    case T_SIZE:
        snprintf(out, cap, "%llu", (unsigned long long)*(const uint64_t *)(const void *)base);
        break;
    case T_BOOL: case T_NOT:
        snprintf(out, cap, "%s", *(const int *)(const void *)base ? "yes" : "no");
        break;
    case T_LEVEL: snprintf(out, cap, "%s", sts_level_name(*(const int *)(const void *)base)); break;
    case T_LOGFMT:
        snprintf(out, cap, "%s", sts_log_format_name(*(const int *)(const void *)base));
        break;
    }
}

int sts_config_diff(const sts_config *a, const sts_config *b, char *out, size_t cap)
{
    int n = 0;
    size_t used = 0;
    if (cap)
        out[0] = 0;
    for (size_t i = 0; i < NOPTS; i++) {
        const opt *o = &OPTS[i];
        if (o->type == T_NOT)
            continue;
        char va[1100], vb[1100];
        fmt_val(a, o, va, sizeof va);
        fmt_val(b, o, vb, sizeof vb);
        if (!strcmp(va, vb))
            continue;
        n++;
        int w;
        if (!strcmp(o->name, "token"))
            w = snprintf(out + used, cap - used, "%stoken: (changed)", n > 1 ? "; " : "");
        else
            w = snprintf(out + used, cap - used, "%s%s: %s -> %s%s", n > 1 ? "; " : "", o->name,
                         va, vb, o->reload ? "" : " (needs a restart)");
        if (w > 0 && (size_t)w < cap - used)
            used += (size_t)w;
    }
    return n;
}
