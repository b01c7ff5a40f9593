/* server/startup.c - loading the data dir into the registry when the daemon starts.
 *
 * Owns: sts_load_datadir and its callbacks (import each manifest's source, publish it - mapped
 * from its native file or imported -, log what was set aside). Does not own: the on-disk rules of a load (store/datadir.c: cleaning
 * tmp/ and trash/, checksums, broken/, retrying sets that need another set), importing a
 * file by format and options (sts_import_path, h_upload.c, shared with UPLOAD_COMMIT), the
 * registry. Called once from sts_server_init (server.c), before any thread starts.
 */
#include "h_upload.h"
#include "native.h"
#include "server.h"
#include "startup.h"

typedef struct load_arg {
    sts_server *srv;
    int         failed;
} load_arg;

static int import_cb(void *arg, const st_manifest *m, const char *source_path, st_set **out,
                     st_error *e)
{
    load_arg *la = arg;
    int rc = sts_import_path(la->srv, source_path, m->format, m->options, 1, out, e);
    if (rc && rc != ST_EBUSY)
        sts_logf(&la->srv->log, STS_ERROR, "data dir: set '%s' (%s) does not import: %s",
                 m->name, source_path, e->msg);
    return rc;
}

static int load_publish_cb(void *arg, const st_manifest *m, st_set *set, st_error *e)
{
    load_arg *la = arg;
    st_set_source src = {m->bytes, m->crc, m->format};
    int mapped = set && set->map;
    int rc = st_registry_put(la->srv->reg, m->name, set, &src, 0, NULL, e);
    if (rc)
        sts_logf(&la->srv->log, STS_ERROR, "data dir: set '%s': %s", m->name, e->msg);
    else
        sts_logf(&la->srv->log, STS_DEBUG, "data dir: loaded '%s' (%s, %llu bytes, %s)", m->name,
                 m->format, (unsigned long long)m->bytes, mapped ? "native file" : "in memory");
    return rc;
}

static void report_cb(void *arg, const char *name, const char *why)
{
    load_arg *la = arg;
    la->failed++;
    sts_logf(&la->srv->log, STS_WARN, "data dir: set '%s': %s", name, why);
}

static void note_cb(void *arg, const char *name, const char *what)
{
    load_arg *la = arg;
    if (name[0])
        sts_logf(&la->srv->log, STS_INFO, "data dir: set '%s': %s", name, what);
    else
        sts_logf(&la->srv->log, STS_INFO, "data dir: %s", what);
}

int sts_load_datadir(sts_server *srv)
{
    if (!srv->dd)
        return 0;
    load_arg la = {srv, 0};
    st_error e;
    st_error_clear(&e);
    int built = 0;
    int64_t t0 = sts_now_ms();
    st_datadir_loader L = {.arg = &la, .import = import_cb, .publish = load_publish_cb,
                           .report = report_cb, .note = note_cb,
                           .native_flags = srv->cfg.verify_native ? ST_NATIVE_VERIFY : 0,
                           .no_native = !srv->cfg.native, .built = &built};
    int n = st_datadir_load_sets(srv->dd, &L, &e);
    if (n < 0) {
        sts_logf(&srv->log, STS_ERROR, "data dir %s: %s", st_datadir_path(srv->dd), e.msg);
        return n;
    }
    if (srv->cfg.native)
        sts_logf(&srv->log, STS_INFO, "data dir %s: %d sets loaded (%d mapped from native files, "
                 "%d native files built), %d set aside or cleaned, %lld ms",
                 st_datadir_path(srv->dd), n, n - built, built, la.failed,
                 (long long)(sts_now_ms() - t0));
    else
        sts_logf(&srv->log, STS_INFO, "data dir %s: %d sets imported (--native no), %d set aside "
                 "or cleaned, %lld ms", st_datadir_path(srv->dd), n, la.failed,
                 (long long)(sts_now_ms() - t0));
    return n;
}
