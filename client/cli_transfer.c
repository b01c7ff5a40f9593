/* client/cli_transfer.c - `seamtex upload`, `seamtex fetch` and `seamtex compress`: the
 * commands that move or transform whole sets, with progress on stderr.
 *
 * Owns: their arguments, the option string of an upload, the compress report. Does not own:
 * chunking, checksums, resume or job polling internals (libseamtex).
 */
#include "cli.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static int progress_cb(void *user, uint64_t done, uint64_t total)
{
    cli_progress_update(user, done, total);
    return 0;
}

static int usage_out(const char *text, int help)
{
    fputs(text, help ? stdout : stderr);
    return help ? CLI_OK : CLI_USAGE;
}

static const char *const UPLOAD_USAGE =
"usage: seamtex upload FILE NAME [options]\n"
"Uploads FILE (Ptex .ptx, an image, EXR, OBJ or Draco mesh, BC1 .dds) as set NAME.\n"
"  --format HINT      ptx | png | jpg | exr | hdr | obj | drc | dds | tif | tga | bmp\n"
"                     (default: FILE's extension, which must be one of those)\n"
"  --texture SET      for a mesh: the set holding its texture (atlas)\n"
"  --cube SPEC        for an environment map: cube layout, e.g. latlong:512 or strip_v\n"
"                     (none auto strip_v strip_h cross_h cross_v latlong[:N] ptex)\n"
"  --options 'k=v ..' more import options, passed as they are\n"
"  --replace          replace an existing set of that name\n"
"  --resume           continue an upload of this file that an earlier run left unfinished\n"
"                     (the server keeps it for a while after a dropped connection)\n"
"  --retries N        on a dropped connection, reconnect and resume up to N times\n"
"                     (default 3; 0 = fail at once)\n";

int cli_cmd_upload(cli_ctx *ctx, int argc, char **argv)
{
    const char *file = NULL, *name = NULL, *hint = NULL, *texture = NULL, *cube = NULL,
               *extra = NULL;
    unsigned flags = 0;
    long retries = 3;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (cli_is_help(a))
            return usage_out(UPLOAD_USAGE, 1);
        if (!strcmp(a, "--replace")) {
            flags |= STC_UPLOAD_REPLACE;
        } else if (!strcmp(a, "--resume")) {
            flags |= STC_UPLOAD_RESUME;
        } else if (!strcmp(a, "--retries")) {
            char *end = NULL;
            if (i + 1 >= argc || (retries = strtol(argv[++i], &end, 10), *end) || retries < 0 ||
                retries > 1000) {
                fprintf(stderr, "seamtex upload: --retries takes a count 0..1000\n");
                return CLI_USAGE;
            }
        } else if (a[0] == '-' && a[1] == '-') {
            if (i + 1 >= argc)
                return usage_out(UPLOAD_USAGE, 0);
            const char *v = argv[++i];
            if (!strcmp(a, "--format"))
                hint = v;
            else if (!strcmp(a, "--texture"))
                texture = v;
            else if (!strcmp(a, "--cube"))
                cube = v;
            else if (!strcmp(a, "--options"))
                extra = v;
            else {
                fprintf(stderr, "seamtex upload: unknown option %s\n", a);
                return CLI_USAGE;
            }
        } else if (!file) {
            file = a;
        } else if (!name) {
            name = a;
        } else {
            return usage_out(UPLOAD_USAGE, 0);
        }
    }
    if (!file || !name)
        return usage_out(UPLOAD_USAGE, 0);
    char options[1024];
    int len = snprintf(options, sizeof options, "%s%s%s%s%s%s", texture ? "texture=" : "",
                       texture ? texture : "", cube ? (texture ? " cube=" : "cube=") : "",
                       cube ? cube : "", extra && (texture || cube) ? " " : "",
                       extra ? extra : "");
    if (len < 0 || (size_t)len >= sizeof options) {
        fprintf(stderr, "seamtex upload: the import options are too long\n");
        return CLI_USAGE;
    }
    if (access(file, R_OK) != 0) {
        fprintf(stderr, "seamtex upload: cannot read %s\n", file);
        return CLI_SERVER;
    }
    int rc = cli_connect(ctx);
    if (rc)
        return rc;
    cli_progress pr;
    cli_progress_init(&pr, "upload", 1);
    stc_upload_opts o;
    memset(&o, 0, sizeof o);
    o.hint = hint;
    o.options = options[0] ? options : NULL;
    o.flags = flags;
    o.progress = progress_cb;
    o.user = &pr;
    stc_upload_result res;
    int e = stc_upload_file(ctx->conn, file, name, &o, &res);
    /* a dropped connection: the server keeps what it received; reconnect and resume */
    /* BUSY while resuming: the server still holds the old connection's upload or is
     * committing it; a moment later it is kept (resumable) or done (COMMIT repeats its reply) */
    for (long attempt = 1;
         attempt <= retries && (e == STC_EIO || e == STC_ECLOSED || e == STC_ECONNECT ||
                                (e == STC_EBUSY && (o.flags & STC_UPLOAD_RESUME)));
         attempt++) {
        cli_progress_end(&pr);
        fprintf(stderr, "seamtex upload: %s (%s); %s (%ld of %ld)\n", stc_strerror(e),
                stc_errmsg(ctx->conn), e == STC_EBUSY ? "retrying" : "reconnecting to resume",
                attempt, retries);
        sleep(1);
        if (e != STC_EBUSY && cli_connect(ctx) != CLI_OK) {
            e = STC_ECONNECT;
            continue;
        }
        if (!(stc_server_info(ctx->conn)->caps & STC_CAP_UPLOAD_RESUME))
            fprintf(stderr, "seamtex upload: the server does not resume uploads; starting over\n");
        o.flags |= STC_UPLOAD_RESUME;
        cli_progress_init(&pr, "upload", 1);
        e = stc_upload_file(ctx->conn, file, name, &o, &res);
    }
    cli_progress_end(&pr);
    if (e)
        return cli_fail(ctx, file, e);
    if (res.resumed_from)
        fprintf(stderr, "seamtex upload: resumed at byte %llu (the whole file's CRC32C was "
                "checked at commit)\n", (unsigned long long)res.resumed_from);
    else if (flags & STC_UPLOAD_RESUME)   /* asked for by --resume, not by a retry */
        fprintf(stderr, "seamtex upload: the server held nothing of this upload to resume; "
                "sent from the start\n");
    char b[32];
    printf("uploaded %s as %s: %s, %u faces, %u x %s, %s in memory (crc32c %08x)\n", file,
           res.name, cli_kind_name(res.kind), res.nfaces, res.nchan, cli_dtype_name(res.dtype),
           cli_bytes(res.memory, b, sizeof b), res.crc32c);
    return CLI_OK;
}

static const char *const FETCH_USAGE =
"usage: seamtex fetch SET FILE [--format ptx|dds|exr|png|obj]\n"
"Downloads a set as a file, checked against the server's CRC32C; written to FILE.part and\n"
"renamed when complete. The format comes from FILE's extension (another extension: ptx)\n"
"unless --format says:\n"
"  ptx  per-face sets; cube sets as a Ptex environment cube\n"
"  exr  cube sets of half or float texels (an EXR cube); atlas images of half or float\n"
"  png  atlas images of u8 or u16 texels\n"
"  obj  an atlas set's mesh (upload it back with --texture <the image set>)\n"
"  dds  BC1 sets\n";

int cli_cmd_fetch(cli_ctx *ctx, int argc, char **argv)
{
    const char *set = NULL, *file = NULL;
    unsigned fmt = STC_FETCH_AUTO;
    for (int i = 1; i < argc; i++) {
        if (cli_is_help(argv[i]))
            return usage_out(FETCH_USAGE, 1);
        if (!strcmp(argv[i], "--format") && i + 1 < argc) {
            char probe[16];
            snprintf(probe, sizeof probe, "x.%.8s", argv[++i]);
            int f = strlen(argv[i]) <= 8 ? stc_fetch_format_for_path(probe) : -1;
            if (f < 0) {
                fprintf(stderr, "seamtex fetch: --format takes ptx, dds, exr, png or obj, not "
                        "'%s'\n", argv[i]);
                return CLI_USAGE;
            }
            fmt = (unsigned)f;
        } else if (argv[i][0] == '-') {
            fprintf(stderr, "seamtex fetch: %s %s (see seamtex fetch --help)\n", argv[i],
                    strcmp(argv[i], "--format") ? "is not an option" : "needs a value");
            return CLI_USAGE;
        } else if (!set) {
            set = argv[i];
        } else if (!file) {
            file = argv[i];
        } else {
            return usage_out(FETCH_USAGE, 0);
        }
    }
    if (!set || !file)
        return usage_out(FETCH_USAGE, 0);
    int rc = cli_connect(ctx);
    if (rc)
        return rc;
    cli_progress pr;
    cli_progress_init(&pr, "fetch", 1);
    int e = stc_fetch_file(ctx->conn, set, fmt, file, progress_cb, &pr);
    cli_progress_end(&pr);
    if (e)
        return cli_fail(ctx, set, e);
    printf("fetched %s into %s\n", set, file);
    return CLI_OK;
}

static const char *const COMPRESS_USAGE =
"usage: seamtex compress SET TARGET [--level 0..9] [--naive] [--replace] [--no-wait] [--json]\n"
"BC1-compresses SET into a new set TARGET on the server, seam-aware by default (--naive\n"
"encodes every block alone), shows the job's progress and a report.\n"
"  --level N          0..9: seamtexd uses its fast encoder for 0-4, high quality for 5-7\n"
"                     (default 5), best for 8-9\n"
"  --replace          replace TARGET if it exists\n"
"  --no-wait          print the job id and return at once\n"
"  --json             the report (or the job id) as one JSON document on stdout\n";

/* The compress report as JSON: the job, its state, and for a finished job the sizes. */
static int compress_json(const char *set, const char *target, unsigned level, unsigned flags,
                         uint64_t job, const stc_job *st, double secs, uint32_t nfaces,
                         uint64_t before, uint64_t after)
{
    static const char *const STATES[] = { "queued", "running", "done", "failed", "canceled" };
    cli_json j;
    cli_json_begin(&j, stdout);
    cli_json_object(&j, NULL);
    cli_json_u64(&j, "job", job);
    cli_json_str(&j, "source", set);
    cli_json_str(&j, "target", target);
    cli_json_u64(&j, "level", level);
    cli_json_bool(&j, "seam_aware", flags & STC_COMPRESS_SEAM_AWARE);
    cli_json_bool(&j, "replace", flags & STC_COMPRESS_REPLACE);
    if (st) {
        cli_json_str(&j, "state", st->state < 5 ? STATES[st->state] : "?");
        cli_json_str(&j, "result", stc_strerror(st->result));
        cli_json_str(&j, "message", st->message);
        cli_json_double(&j, "seconds", secs);
        if (st->state == STC_JOB_DONE) {
            cli_json_u64(&j, "faces", nfaces);
            cli_json_u64(&j, "texel_bytes_before", before);
            cli_json_u64(&j, "texel_bytes_after", after);
            if (after > 0)
                cli_json_double(&j, "ratio", (double)before / (double)after);
        }
    }
    cli_json_close(&j);
    return cli_json_finish(&j);
}

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

int cli_cmd_compress(cli_ctx *ctx, int argc, char **argv)
{
    const char *set = NULL, *target = NULL;
    uint32_t level = 5;
    unsigned flags = STC_COMPRESS_SEAM_AWARE;
    int wait = 1, json = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (cli_is_help(a))
            return usage_out(COMPRESS_USAGE, 1);
        if (!strcmp(a, "--json")) {
            json = 1;
            continue;
        }
        if (!strcmp(a, "--level") && i + 1 < argc) {
            if (cli_parse_u32(argv[++i], &level) || level > 9) {
                fprintf(stderr, "seamtex compress: --level takes 0..9, not '%s'\n", argv[i]);
                return CLI_USAGE;
            }
        } else if (!strcmp(a, "--naive")) {
            flags &= ~(unsigned)STC_COMPRESS_SEAM_AWARE;
        } else if (!strcmp(a, "--replace")) {
            flags |= STC_COMPRESS_REPLACE;
        } else if (!strcmp(a, "--no-wait")) {
            wait = 0;
        } else if (a[0] == '-') {
            fprintf(stderr, "seamtex compress: %s %s (see seamtex compress --help)\n", a,
                    strcmp(a, "--level") ? "is not an option" : "needs a value");
            return CLI_USAGE;
        } else if (!set) {
            set = a;
        } else if (!target) {
            target = a;
        } else {
            return usage_out(COMPRESS_USAGE, 0);
        }
    }
    if (!set || !target)
        return usage_out(COMPRESS_USAGE, 0);
    int rc = cli_connect(ctx);
    if (rc)
        return rc;
    uint64_t t0 = now_ns(), job = 0;
    int e = stc_compress(ctx->conn, set, target, level, flags, &job);
    if (e)
        return cli_fail(ctx, "compress", e);
    if (!wait) {
        if (json)
            return compress_json(set, target, level, flags, job, NULL, 0, 0, 0, 0);
        printf("job %llu started\n", (unsigned long long)job);
        return CLI_OK;
    }
    cli_progress pr;
    cli_progress_init(&pr, "compress", 0);
    stc_job st;
    for (;;) {
        e = stc_job_status(ctx->conn, job, &st);
        if (e) {
            cli_progress_end(&pr);
            return cli_fail(ctx, "job status", e);
        }
        cli_progress_update(&pr, (uint64_t)(st.progress * 1000.0f), 1000);
        if (st.state != STC_JOB_QUEUED && st.state != STC_JOB_RUNNING)
            break;
        struct timespec ts = { 0, 100000000L };
        nanosleep(&ts, NULL);
    }
    cli_progress_end(&pr);
    double secs = (now_ns() - t0) / 1e9;
    if (st.state != STC_JOB_DONE) {
        fprintf(stderr, "seamtex compress: job %llu %s: %s%s%s\n", (unsigned long long)job,
                st.state == STC_JOB_CANCELED ? "was cancelled" : "failed",
                stc_strerror(st.result), st.message[0] ? ": " : "", st.message);
        if (json)
            compress_json(set, target, level, flags, job, &st, secs, 0, 0, 0);
        return CLI_SERVER;
    }
    /* the report: sizes before and after */
    stc_info a, b;
    uint64_t before = 0, after = 0;
    uint32_t nfaces = 0;
    if (stc_info_get(ctx->conn, set, 0, 0, &a) == 0) {
        before = a.texel_bytes;
        nfaces = a.nfaces;
    }
    if (stc_info_get(ctx->conn, target, 0, 0, &b) == 0)
        after = b.texel_bytes;
    if (json)
        return compress_json(set, target, level, flags, job, &st, secs, nfaces, before, after);
    char s1[32], s2[32];
    printf("compressed %s -> %s (%s, level %u) in %.2f s: %u faces, texels %s -> %s",
           set, target, flags & STC_COMPRESS_SEAM_AWARE ? "seam-aware" : "naive", level, secs,
           nfaces, cli_bytes(before, s1, sizeof s1), cli_bytes(after, s2, sizeof s2));
    if (after > 0)
        printf(" (%.1f:1)", (double)before / (double)after);
    printf("\n");
    if (st.message[0])
        printf("%s\n", st.message);
    return CLI_OK;
}
