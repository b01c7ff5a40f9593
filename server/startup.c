/* server/startup.c - loading the data dir into the registry when the daemon starts.
 *
 * Owns: sts_load_datadir and its callbacks (import each manifest's source, publish it, log
 * what was set aside). Does not own: the on-disk rules of a load (store/datadir.c: cleaning
 * tmp/ and trash/, checksums, broken/, retrying sets that need another set), importing a
 * file by format and options (sts_import_path, h_upload.c, shared with UPLOAD_COMMIT), the
 * registry. Called once from sts_server_init (server.c), before any thread starts.
 */
#include "h_upload.h"
#include "server.h"
#include "startup.h"

typedef struct load_arg {
    sts_server *srv;
    int         failed;
} load_arg;

static int load_cb(void *arg, const st_manifest *m, const char *source_path)
{
    load_arg *la = arg;
    st_error e;
    st_error_clear(&e);
    st_set *set = NULL;
    int rc = sts_import_path(la->srv, source_path, m->format, m->options, &set, &e);
    if (rc == ST_EBUSY)
        return rc;
    if (rc) {
        sts_logf(&la->srv->log, STS_ERROR, "data dir: set '%s' (%s) does not import: %s",
                 m->name, source_path, e.msg);
        return rc;
    }
    st_set_source src = {m->bytes, m->crc, m->format};
    rc = st_registry_put(la->srv->reg, m->name, set, &src, 0, NULL, &e);
    if (rc)
        sts_logf(&la->srv->log, STS_ERROR, "data dir: set '%s': %s", m->name, e.msg);
    else
        sts_logf(&la->srv->log, STS_DEBUG, "data dir: loaded '%s' (%s, %llu bytes)", m->name,
                 m->format, (unsigned long long)m->bytes);
    return rc;
}

static void report_cb(void *arg, const char *name, const char *why)
{
    load_arg *la = arg;
    la->failed++;
    sts_logf(&la->srv->log, STS_WARN, "data dir: set '%s': %s", name, why);
}

int sts_load_datadir(sts_server *srv)
{
    if (!srv->dd)
        return 0;
    load_arg la = {srv, 0};
    st_error e;
    st_error_clear(&e);
    int n = st_datadir_load(srv->dd, load_cb, &la, report_cb, &e);
    if (n < 0) {
        sts_logf(&srv->log, STS_ERROR, "data dir %s: %s", st_datadir_path(srv->dd), e.msg);
        return n;
    }
    sts_logf(&srv->log, STS_INFO, "data dir %s: %d sets loaded, %d set aside or cleaned",
             st_datadir_path(srv->dd), n, la.failed);
    return n;
}
