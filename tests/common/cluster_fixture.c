/* tests/common/cluster_fixture.c - see cluster_fixture.h. */
#include "cluster_fixture.h"

#include <fcntl.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#include "daemon_client.h"
#include "ptx_fixture.h"
#include "wait.h"

int st_cluster_node_start(st_daemon *d, const char *etcd_url, int idx, unsigned R, unsigned W)
{
    char id[16], r[12], w[12];
    snprintf(id, sizeof id, "n%d", idx);
    snprintf(r, sizeof r, "%u", R);
    snprintf(w, sizeof w, "%u", W ? W : R);
    const char *args[] = {"--cluster", etcd_url, "--node-id", id, "--advertise", "127.0.0.1:0",
                          "--replicas", r, "--write-quorum", w, "--lease-ttl", "2",
                          "--repair-interval", "1", "--no-default-set", NULL};
    return st_daemon_start(d, args);
}

stc_cluster *st_cluster_open_nodes(const st_daemon *nodes, int n)
{
    char seeds[512], msg[256];
    size_t len = 0;
    seeds[0] = 0;
    for (int i = 0; i < n && len < sizeof seeds; i++)
        len += (size_t)snprintf(seeds + len, sizeof seeds - len, "%s127.0.0.1:%d", i ? "," : "",
                                nodes[i].port);
    int err = 0;
    return stc_cluster_open(seeds, NULL, &err, msg, sizeof msg);
}

int st_cluster_all_see(const st_daemon *nodes, int n, uint64_t members)
{
    for (int i = 0; i < n; i++)
        if (st_daemon_stat(&nodes[i], "cluster_members") != members ||
            st_daemon_stat(&nodes[i], "cluster_etcd_ok") != 1)
            return 0;
    return 1;
}

int st_cluster_tint_files(const char *dir, int n, int step, char (*files)[300])
{
    for (int t = 0; t < n; t++) {
        size_t len = 0;
        void *p = st_fixture_default_ptx(&len, t * step);
        if (!p)
            return -1;
        snprintf(files[t], 300, "%s/tint%d.ptx", dir, t);
        FILE *f = fopen(files[t], "wb");
        size_t put = f ? fwrite(p, 1, len, f) : 0;
        int bad = !f || put != len;
        if (f && fclose(f) != 0)
            bad = 1;
        free(p);
        if (bad) {
            fprintf(stderr, "cannot write %s\n", files[t]);
            return -1;
        }
    }
    return 0;
}

void st_red_query(stc_sample_opts *o, stc_query *q)
{
    memset(o, 0, sizeof *o);
    o->mode = 1;
    memset(q, 0, sizeof *q);
    q->u = 0.5f;
    q->v = 0.5f;
}

int st_red_at(stc_conn *c, const char *set, float *red)
{
    stc_sample_opts o;
    stc_query q;
    stc_sample_result r;
    st_red_query(&o, &q);
    int rc = stc_sample(c, set, &o, &q, 1, &r);
    if (rc == 0)
        *red = ((const float *)r.values)[0];
    return rc;
}

float st_red_on(const st_daemon *d, const char *set)
{
    stc_conn *c = st_daemon_client(d, NULL);
    float r = -1;
    if (!c || st_red_at(c, set, &r) != 0)
        r = -1;
    stc_close(c);
    return r;
}

int st_cluster_red_at(stc_cluster *cl, const char *set, float *red)
{
    stc_sample_opts o;
    stc_query q;
    stc_sample_result r;
    st_red_query(&o, &q);
    int rc = stc_cluster_sample(cl, set, &o, &q, 1, &r);
    if (rc == 0)
        *red = ((const float *)r.values)[0];
    return rc;
}

int st_cluster_tint_reds(stc_cluster *cl, int n, char (*files)[300], float *red)
{
    for (int t = 0; t < n; t++) {
        int rc = stc_cluster_upload_file(cl, files[t], "probe", NULL, NULL);
        if (!rc)
            rc = st_cluster_red_at(cl, "probe", &red[t]);
        if (!rc)
            rc = stc_cluster_delete(cl, "probe");
        if (rc)
            return rc;
    }
    return 0;
}

extern char **environ;

int st_cluster_cli(const char *dir, const char *where, const char *const *args, char *out,
                   size_t cap)
{
    char prog[512], outf[400];
    const char *b = getenv("SEAMTEX_BUILD");
    snprintf(prog, sizeof prog, "%s/seamtex", b && *b ? b : "build");
    snprintf(outf, sizeof outf, "%s/cli.out", dir);
    const char *argv[16] = {prog, "--cluster", where};
    int ac = 3;
    for (int i = 0; args[i] && ac < 15; i++)
        argv[ac++] = args[i];
    argv[ac] = NULL;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, outf, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    pid_t pid;
    int rc = posix_spawn(&pid, prog, &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0)
        return -1;
    int st;
    while (waitpid(pid, &st, 0) < 0)
        ;
    FILE *f = fopen(outf, "rb");
    size_t n = f ? fread(out, 1, cap - 1, f) : 0;
    out[n] = 0;
    if (f)
        fclose(f);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

int st_cluster_read_all_for(stc_cluster *cl, const char *const *names, int n, const float *want,
                            int ms)
{
    int bad = 0, reads = 0;
    for (int t = 0; t < ms; t += 50) {
        for (int s = 0; s < n; s++) {
            float red = -1;
            int rc = st_cluster_red_at(cl, names[s], &red);
            reads++;
            if (rc != 0 || red != want[s]) {
                if (bad < 5)
                    fprintf(stderr, "'%s': rc %d red %g (want %g)\n", names[s], rc, red,
                            want[s]);
                bad++;
            }
        }
        st_sleep_ms(50);
    }
    fprintf(stderr, "%d reads, %d failed or other contents\n", reads, bad);
    return bad;
}
