/* tests/bench/bench_proto.c - cost of the wire protocol and of libseamtex's transport.
 *
 * Measures: CRC32C (SSE4.2 and slice-by-8 paths), SAMPLE request encode and decode (queries
 * per second, 4096 per frame), SAMPLE reply encode (f32 and unorm8, RGBA) and client-side
 * decode, and libseamtex over loopback against a minimal in-process echo server (a thread
 * that answers HELLO and PING): blocking PING round trip and pipelined PINGs per second.
 * The echo server does no work, so the last two are the client library + kernel cost.
 * Then, when build/seamtexd and the shared data are there, against the real daemon on
 * loopback (one connection): upload and fetch of cube.ptx (2.37 MB) in MB/s, a one-query
 * SAMPLE round trip, and pipelined 4096-query bilinear SAMPLE batches in M queries/s.
 *
 * Usage: bench_proto [--json PATH] [--reps N]   (medians of N repetitions, default 5)
 */
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "../common/daemon_fixture.h"
#include "../common/wire.h"
#include "proto.h"
#include "seamtex.h"

#include "crc32c.h"
#include "../common/benchstat.h"

/* ---- echo server ------------------------------------------------------------------------- */

typedef struct echo {
    int lfd, port, stop;
    pthread_t th;
} echo;


static void *echo_main(void *arg)
{
    echo *e = arg;
    int fd = -1;
    stp_buf in, out;
    stp_buf_init(&in);
    stp_buf_init(&out);
    while (!e->stop) {
        if (fd < 0) {
            struct pollfd p = { e->lfd, POLLIN, 0 };
            if (poll(&p, 1, 50) > 0)
                fd = accept(e->lfd, NULL, NULL);
            continue;
        }
        struct pollfd p = { fd, POLLIN, 0 };
        if (poll(&p, 1, 50) <= 0)
            continue;
        stp_buf_reserve(&in, 1 << 16);
        ssize_t n = recv(fd, in.data + in.len, in.cap - in.len, 0);
        if (n <= 0) {
            close(fd);
            fd = -1;
            stp_buf_clear(&in);
            continue;
        }
        in.len += (size_t)n;
        for (;;) {
            stp_header h;
            if (stp_parse_header(stp_buf_head(&in), stp_buf_avail(&in), 1 << 20, &h, NULL) !=
                    STP_OK || stp_buf_avail(&in) < STP_HEADER_SIZE + (size_t)h.body_len)
                break;
            if (h.opcode == STP_OP_HELLO) {
                stp_hello_reply r;
                memset(&r, 0, sizeof r);
                r.version = 1;
                r.caps = STP_CAP_PIPELINE;
                r.max_body = r.max_chunk = 1 << 20;
                r.max_batch = 4096;
                r.max_inflight = 256;
                stp_enc_hello_reply(&out, h.reqid, &r);
            } else {
                stp_enc_raw(&out, h.opcode, STP_F_REPLY, h.reqid, 0, 0,
                            stp_buf_head(&in) + STP_HEADER_SIZE, h.body_len);
            }
            stp_buf_consume(&in, STP_HEADER_SIZE + h.body_len);
        }
        (void)st_wire_send_all(fd, stp_buf_head(&out), stp_buf_avail(&out));
        stp_buf_clear(&out);
    }
    if (fd >= 0)
        close(fd);
    stp_buf_free(&in);
    stp_buf_free(&out);
    return NULL;
}

static int echo_start(echo *e)
{
    struct sockaddr_in sa;
    socklen_t sl = sizeof sa;
    memset(e, 0, sizeof *e);
    e->lfd = socket(AF_INET, SOCK_STREAM, 0);
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (bind(e->lfd, (struct sockaddr *)&sa, sizeof sa) || listen(e->lfd, 4))
        return -1;
    getsockname(e->lfd, (struct sockaddr *)&sa, &sl);
    e->port = ntohs(sa.sin_port);
    return pthread_create(&e->th, NULL, echo_main, e);
}

static void echo_stop(echo *e)
{
    e->stop = 1;
    pthread_join(e->th, NULL);
    close(e->lfd);
}

/* Records when the last chunk was acknowledged (to split transfer from commit). */
static int note_progress(void *user, uint64_t done, uint64_t total)
{
    if (done == total)
        *(double *)user = st_bench_now();
    return 0;
}

/* ---- main -------------------------------------------------------------------------------------- */

#define NQ 4096

int main(int argc, char **argv)
{
    const char *json;
    int reps;
    if (st_bench_args(argc, argv, &json, &reps, 5) != 0)
        return 2;
    double *t = calloc((size_t)reps, sizeof *t);

    /* CRC32C over 32 MiB */
    size_t clen = 32u << 20;
    uint8_t *cbuf = malloc(clen);
    for (size_t i = 0; i < clen; i++)
        cbuf[i] = (uint8_t)(i * 2654435761u >> 13);
    volatile uint32_t sink = 0;
    for (int r = 0; r < reps; r++) {
        double t0 = st_bench_now();
        sink ^= stp_crc32c(0, cbuf, clen);
        t[r] = clen / (st_bench_now() - t0) / 1e9;
    }
    double crc_hw = st_bench_median(t, reps);
    for (int r = 0; r < reps; r++) {
        double t0 = st_bench_now();
        sink ^= stu_crc32c_sw(0, cbuf, clen / 4);
        t[r] = clen / 4 / (st_bench_now() - t0) / 1e9;
    }
    double crc_sw = st_bench_median(t, reps);
    free(cbuf);

    /* SAMPLE request encode / decode, 4096 queries per frame, 64 frames per timing */
    stp_query *q = malloc(NQ * sizeof *q);
    for (int i = 0; i < NQ; i++) {
        stp_query x = { (uint32_t)i % 384, (i % 97) / 97.0f, (i % 89) / 89.0f, 0.001f, 0, 0,
                        0.001f };
        q[i] = x;
    }
    stp_sample_req rq;
    memset(&rq, 0, sizeof rq);
    strcpy(rq.p.name, "default");
    rq.p.filter = 1;
    rq.count = NQ;
    rq.queries = q;
    stp_buf b;
    stp_buf_init(&b);
    for (int r = 0; r < reps; r++) {
        double t0 = st_bench_now();
        for (int k = 0; k < 64; k++) {
            stp_buf_clear(&b);
            stp_enc_sample_req(&b, (uint32_t)k, 0, &rq);
        }
        t[r] = 64.0 * NQ / (st_bench_now() - t0) / 1e6;
    }
    double enc_req = st_bench_median(t, reps);
    stp_sample_req d;
    stp_query g;
    for (int r = 0; r < reps; r++) {
        double t0 = st_bench_now();
        for (int k = 0; k < 64; k++) {
            stp_dec_sample_req(b.data + STP_HEADER_SIZE, b.len - STP_HEADER_SIZE, NQ, &d, NULL);
            for (uint32_t i = 0; i < d.count; i++) {
                stp_sample_query(&d, i, &g);
                sink ^= g.face;
            }
        }
        t[r] = 64.0 * NQ / (st_bench_now() - t0) / 1e6;
    }
    double dec_req = st_bench_median(t, reps);

    /* SAMPLE reply, RGBA, with coverage and status */
    float *vals = malloc(NQ * 4 * sizeof *vals), *cov = malloc(NQ * sizeof *cov);
    uint8_t *st = calloc(NQ, 1);
    for (int i = 0; i < NQ * 4; i++)
        vals[i] = (i % 255) / 255.0f;
    for (int i = 0; i < NQ; i++)
        cov[i] = 1.0f;
    double enc_rep[2], dec_rep = 0;
    float *outv = malloc(NQ * 4 * sizeof *outv);
    for (int fmt = 0; fmt < 2; fmt++) {
        stp_sample_reply rp = { NQ, 4, (uint8_t)fmt, STP_SF_COVERAGE | STP_SF_STATUS, 0, vals,
                                cov, st, NULL, NULL, NULL };
        for (int r = 0; r < reps; r++) {
            double t0 = st_bench_now();
            for (int k = 0; k < 64; k++) {
                stp_buf_clear(&b);
                stp_enc_sample_reply(&b, STP_OP_SAMPLE, (uint32_t)k, &rp);
            }
            t[r] = 64.0 * NQ / (st_bench_now() - t0) / 1e6;
        }
        enc_rep[fmt] = st_bench_median(t, reps);
        if (fmt == 0) {
            stp_sample_reply dr;
            for (int r = 0; r < reps; r++) {
                double t0 = st_bench_now();
                for (int k = 0; k < 64; k++) {
                    stp_dec_sample_reply(b.data + STP_HEADER_SIZE, b.len - STP_HEADER_SIZE, &dr,
                                         NULL);
                    stp_sample_values_f32(&dr, outv);
                    stp_sample_coverage(&dr, cov);
                }
                t[r] = 64.0 * NQ / (st_bench_now() - t0) / 1e6;
            }
            dec_rep = st_bench_median(t, reps);
        }
    }

    /* libseamtex over loopback against the echo thread */
    double rtt_us = 0, pipe_kps = 0;
    echo e;
    if (echo_start(&e) == 0) {
        int err;
        stc_conn *c = stc_connect("127.0.0.1", (unsigned)e.port, 2000, &err);
        if (c) {
            stc_set_timeout(c, 5000);
            int n = 2000;
            double *lat = malloc((size_t)n * sizeof *lat);
            for (int i = 0; i < 200; i++)
                stc_ping(c);
            for (int i = 0; i < n; i++) {
                double t0 = st_bench_now();
                stc_ping(c);
                lat[i] = (st_bench_now() - t0) * 1e6;
            }
            rtt_us = st_bench_median(lat, n);
            free(lat);
            for (int r = 0; r < reps; r++) {
                int total = 20000, window = 64, sent = 0, got = 0;
                uint32_t id;
                stc_reply rep;
                double t0 = st_bench_now();
                while (got < total) {
                    while (sent < total && sent - got < window) {
                        stc_append_ping(c, "0123456789abcdef", 16, &id);
                        sent++;
                    }
                    if (stc_get_reply(c, 5000, &rep) != 0)
                        break;
                    got++;
                }
                t[r] = got / (st_bench_now() - t0) / 1e3;
            }
            pipe_kps = st_bench_median(t, reps);
            stc_close(c);
        }
        echo_stop(&e);
    }

    /* against seamtexd */
    double up_mbps = 0, chunks_mbps = 0, commit_ms = 0, fetch_mbps = 0, srtt_us = 0, spipe_mqps = 0;
    st_daemon dm;
    char ptx[512];
    if (st_daemon_data_path(ptx, sizeof ptx, "ptx/wdas-ptex-2009/cube/text/cube.ptx") == 0 &&
        st_daemon_init(&dm) == 0 && st_daemon_start(&dm, NULL) == 0) {
        int err;
        stc_conn *c = stc_connect(dm.host, (unsigned)dm.port, 5000, &err);
        if (c) {
            stc_set_timeout(c, 60000);
            stc_upload_opts uo;
            stc_upload_result ur;
            FILE *fp = fopen(ptx, "rb");
            fseek(fp, 0, SEEK_END);
            double mb = ftell(fp) / 1e6;
            fclose(fp);
            memset(&uo, 0, sizeof uo);
            uo.flags = STC_UPLOAD_REPLACE;
            double *t2 = calloc((size_t)reps, sizeof *t2), *t3 = calloc((size_t)reps, sizeof *t3);
            double acked = 0;
            uo.progress = note_progress;
            uo.user = &acked;
            for (int r = 0; r < reps; r++) {
                double t0 = st_bench_now();
                if (stc_upload_file(c, ptx, "bench_cube", &uo, &ur) != 0)
                    break;
                double t1 = st_bench_now();
                t[r] = mb / (t1 - t0);
                t2[r] = mb / (acked - t0);
                t3[r] = (t1 - acked) * 1e3;
            }
            up_mbps = st_bench_median(t, reps);
            chunks_mbps = st_bench_median(t2, reps);
            commit_ms = st_bench_median(t3, reps);
            free(t2);
            free(t3);
            char out[600];
            snprintf(out, sizeof out, "%s/fetched.ptx", dm.dir);
            for (int r = 0; r < reps; r++) {
                double t0 = st_bench_now();
                if (stc_fetch_file(c, "bench_cube", STC_FETCH_PTX, out, NULL, NULL) != 0)
                    break;
                fp = fopen(out, "rb");
                fseek(fp, 0, SEEK_END);
                t[r] = ftell(fp) / 1e6 / (st_bench_now() - t0);
                fclose(fp);
            }
            fetch_mbps = st_bench_median(t, reps);
            unlink(out);
            stc_query *sq = malloc(NQ * sizeof *sq);
            for (int i = 0; i < NQ; i++) {
                stc_query x = { (uint32_t)(i % 72), (i % 61) / 61.0f, (i % 59) / 59.0f,
                                0.002f, 0, 0, 0.002f };
                sq[i] = x;
            }
            stc_sample_opts so;
            stc_sample_result res;
            memset(&so, 0, sizeof so);
            so.mode = 1;
            so.filter = 1;
            int n = 500;
            double *lat = malloc((size_t)n * sizeof *lat);
            for (int i = 0; i < n; i++) {
                double t0 = st_bench_now();
                stc_sample(c, "bench_cube", &so, sq + (i % NQ), 1, &res);
                lat[i] = (st_bench_now() - t0) * 1e6;
            }
            srtt_us = st_bench_median(lat, n);
            free(lat);
            for (int r = 0; r < reps; r++) {
                int total = 64, window = 4, sent = 0, got = 0;
                uint32_t id;
                stc_reply rep;
                double t0 = st_bench_now();
                while (got < total) {
                    while (sent < total && sent - got < window) {
                        stc_append_sample(c, "bench_cube", &so, sq, NQ, &id);
                        sent++;
                    }
                    if (stc_get_reply(c, 60000, &rep) != 0 || rep.status != 0)
                        break;
                    got++;
                }
                t[r] = (double)got * NQ / (st_bench_now() - t0) / 1e6;
            }
            spipe_mqps = st_bench_median(t, reps);
            free(sq);
            stc_close(c);
        }
        st_daemon_cleanup(&dm);
    } else {
        fprintf(stderr, "note: seamtexd or the shared data missing: daemon figures skipped\n");
    }

    printf("%-52s %12s\n", "measure", "median");
    printf("%-52s %9.2f GB/s\n", "CRC32C, SSE4.2 path (32 MiB)", crc_hw);
    printf("%-52s %9.2f GB/s\n", "CRC32C, slice-by-8 path (8 MiB)", crc_sw);
    printf("%-52s %9.1f Mq/s\n", "SAMPLE request encode (4096 queries/frame)", enc_req);
    printf("%-52s %9.1f Mq/s\n", "SAMPLE request decode + query extraction", dec_req);
    printf("%-52s %9.1f Mq/s\n", "SAMPLE reply encode, RGBA f32 + coverage + status", enc_rep[0]);
    printf("%-52s %9.1f Mq/s\n", "SAMPLE reply encode, RGBA unorm8 + cov + status", enc_rep[1]);
    printf("%-52s %9.1f Mq/s\n", "SAMPLE reply decode to floats (f32, RGBA)", dec_rep);
    printf("%-52s %9.1f us\n", "libseamtex blocking PING round trip (loopback echo)", rtt_us);
    printf("%-52s %9.1f k/s\n", "libseamtex pipelined PINGs, window 64 (loopback)", pipe_kps);
    printf("%-52s %9.1f MB/s\n", "seamtexd: upload cube.ptx (2.37 MB), commit included", up_mbps);
    printf("%-52s %9.1f MB/s\n", "  of which: chunks sent and acknowledged", chunks_mbps);
    printf("%-52s %9.1f ms\n", "  of which: COMMIT (import + durable write)", commit_ms);
    printf("%-52s %9.1f MB/s\n", "seamtexd: fetch it back as .ptx (CRC checked)", fetch_mbps);
    printf("%-52s %9.1f us\n", "seamtexd: one-query bilinear SAMPLE round trip", srtt_us);
    printf("%-52s %9.2f Mq/s\n", "seamtexd: pipelined 4096-query SAMPLE, 1 connection", spipe_mqps);
    printf("(medians of %d repetitions; 2-core machine shared with other jobs)\n", reps);

    if (json) {
        FILE *fp = fopen(json, "w");
        if (!fp) {
            perror(json);
            return 1;
        }
        fprintf(fp, "{\n  \"bench\": \"bench_proto\",\n  \"reps\": %d,\n"
                "  \"crc32c_hw_gbps\": %.3f,\n  \"crc32c_sw_gbps\": %.3f,\n"
                "  \"sample_req_encode_mqps\": %.2f,\n  \"sample_req_decode_mqps\": %.2f,\n"
                "  \"sample_reply_encode_f32_mqps\": %.2f,\n"
                "  \"sample_reply_encode_unorm8_mqps\": %.2f,\n"
                "  \"sample_reply_decode_f32_mqps\": %.2f,\n"
                "  \"client_ping_rtt_us\": %.2f,\n  \"client_pipelined_ping_kps\": %.2f,\n"
                "  \"daemon_upload_mbps\": %.2f,\n  \"daemon_upload_chunks_mbps\": %.2f,\n"
                "  \"daemon_upload_commit_ms\": %.1f,\n  \"daemon_fetch_mbps\": %.2f,\n"
                "  \"daemon_sample1_rtt_us\": %.2f,\n  \"daemon_sample_pipelined_mqps\": %.3f\n}\n",
                reps, crc_hw, crc_sw, enc_req, dec_req, enc_rep[0], enc_rep[1], dec_rep, rtt_us,
                pipe_kps, up_mbps, chunks_mbps, commit_ms, fetch_mbps, srtt_us, spipe_mqps);
        fclose(fp);
    }
    (void)sink;
    free(q);
    free(vals);
    free(cov);
    free(st);
    free(outv);
    free(t);
    stp_buf_free(&b);
    return 0;
}
