/* render/app.c - what seamtex-render's jobs share: finding a mesh's texture, naming its set,
 * connecting to the daemon and uploading the texture.
 *
 * Owns: those steps and their messages. Does not own: the connection's lifetime (the caller
 * closes it).
 */
#include "app.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "unixaddr.h"

int app_texture_for(const app_cfg *c, const char *mesh, char *path, size_t cap, int *kind,
                    const char **image, char *msg, size_t ml)
{
    size_t n = strlen(mesh);
    *image = NULL;
    if (n < 4 || strcmp(mesh + n - 4, ".obj") != 0 || n + 1 > cap) {
        snprintf(msg, ml, "%.300s: the mesh must be an .obj file", mesh);
        return -1;
    }
    if (access(mesh, R_OK) != 0) {   /* said first: not "no .ptx beside it" for a mistyped mesh */
        snprintf(msg, ml, "%.300s: cannot read the mesh: %s", mesh, strerror(errno));
        return -1;
    }
    if (c->texture) {
        size_t t = strlen(c->texture);
        if (t >= 4 && strcmp(c->texture + t - 4, ".ptx") == 0) {
            *kind = RM_PTEX;
            snprintf(path, cap, "%s", c->texture);
        } else {   /* an atlas set: the mesh uploaded with its image */
            *kind = RM_ATLAS;
            *image = c->texture;
            snprintf(path, cap, "%s", mesh);
        }
        return 0;
    }
    snprintf(path, cap, "%.*s.ptx", (int)(n - 4), mesh);
    if (access(path, R_OK) == 0) {
        *kind = RM_PTEX;
        return 0;
    }
    snprintf(msg, ml, "%.300s: no %.300s beside it; an atlas mesh needs --texture IMAGE", mesh,
             path);
    return -1;
}

void app_set_name(const char *path, const char *prefix, char *name, size_t cap)
{
    const char *b = strrchr(path, '/');
    b = b ? b + 1 : path;
    size_t n = strcspn(b, ".");
    snprintf(name, cap, "%s%.*s", prefix, (int)n, b);
    for (char *p = name; *p; p++)
        if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') ||
              *p == '-' || *p == '_' || *p == '.'))
            *p = '_';
}

int app_connect(const app_cfg *c, stc_conn **conn, char *msg, size_t ml)
{
    if (*conn)
        return 0;
    if (!c->port && !stu_is_unix_addr(c->host)) {
        snprintf(msg, ml, "no daemon: give --port or --host unix:PATH (or --inproc)");
        return -1;
    }
    int err = 0;
    stc_opts o = { .connect_timeout_ms = 5000, .request_timeout_ms = 120000,
                   .client_name = "seamtex-render" };
    *conn = stc_connect_opts(c->host, c->port, &o, &err, msg, ml);
    if (!*conn)
        return -1;
    char note[512];
    int rc = rs_net_shm(*conn, c->host, c->shm, c->batch, c->inflight, c->outfmt, note,
                        sizeof note, msg, ml);
    if (rc == 0 && c->shm == RS_SHM_AUTO && stu_is_unix_addr(c->host))
        fprintf(stderr, "seamtex-render: sampling over the socket: %s\n", note);
    return rc < 0 ? -1 : 0;
}

int app_upload(const app_cfg *c, stc_conn *conn, const char *path, const char *image,
               const char *name, char *msg, size_t ml)
{
    if (c->no_upload)
        return 0;
    stc_upload_opts o = { .flags = STC_UPLOAD_REPLACE };
    stc_upload_result r;
    char tex[300], opts[320];
    if (image) {
        snprintf(tex, sizeof tex, "%.250s-tex", name);
        if (app_upload(c, conn, image, NULL, tex, msg, ml) != 0)
            return -1;
        snprintf(opts, sizeof opts, "texture=%s", tex);
        o.options = opts;
    }
    int rc = stc_upload_file(conn, path, name, &o, &r);
    if (rc != 0) {
        snprintf(msg, ml, "uploading %s as %s: %s (%s)", path, name, stc_strerror(rc),
                 stc_errmsg(conn));
        return -1;
    }
    return 0;
}
