// ptexopen - Ptex's "open + decode every face's level 0", timed.
//
// usage: ptexopen FILE.ptx [--reps N] [--warm]
//   One run = PtexTexture::open(path) (no PtexCache: the reader keeps what it reads, nothing
//   is evicted) + getData(faceid, buffer, 0) for every face at its full resolution (level 0)
//   into one buffer sized for the largest face + release. Constant faces are filled to their
//   full resolution, as getData does. File in the page cache (one untimed run first).
//   Each timed run is a fresh process (this binary again with --one: a fresh heap, as
//   seamtex's bench_ptex import figures are taken). Prints the median of --reps (default 9)
//   runs of wall time and process CPU time, and the per-run values. --warm also times
//   runs repeated inside this process.
//   --one FILE: one run in this process; prints "wall_s cpu_s".
#include <Ptexture.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <vector>

#include "harness.h"

namespace {

// one open + level-0 decode; returns 0, fills wall / cpu seconds and a checksum
int one(const char* path, double* wall, double* cpu, unsigned long* sum, long* bytes)
{
    double w0 = harness_clock(CLOCK_MONOTONIC), c0 = harness_clock(CLOCK_PROCESS_CPUTIME_ID);
    Ptex::String err;
    PtexTexture* tx = PtexTexture::open(path, err, false);
    if (!tx) { fprintf(stderr, "%s: %s\n", path, err.c_str()); return 1; }
    int nf = tx->numFaces();
    int psize = Ptex::DataSize(tx->dataType()) * tx->numChannels();
    size_t maxsize = 0;
    for (int f = 0; f < nf; f++) {
        size_t s = (size_t)tx->getFaceInfo(f).res.size() * (size_t)psize;
        if (s > maxsize) maxsize = s;
    }
    std::vector<char> buf(maxsize ? maxsize : 1);
    unsigned long s = 0;
    long total = 0;
    for (int f = 0; f < nf; f++) {
        const Ptex::FaceInfo& fi = tx->getFaceInfo(f);
        tx->getData(f, &buf[0], 0);
        size_t n = (size_t)fi.res.size() * (size_t)psize;
        s += (unsigned char)buf[0] + (unsigned char)buf[n - 1];
        total += (long)n;
    }
    tx->release();
    *wall = harness_clock(CLOCK_MONOTONIC) - w0;
    *cpu = harness_clock(CLOCK_PROCESS_CPUTIME_ID) - c0;
    *sum = s;
    *bytes = total;
    return 0;
}

int fresh(const char* self, const char* path, double* wall, double* cpu)
{
    int fd[2];
    if (pipe(fd)) return -1;
    pid_t pid = fork();
    if (pid < 0) return -1;
    if (pid == 0) {
        close(fd[0]);
        if (dup2(fd[1], 1) < 0) _exit(127);
        execl(self, "ptexopen", "--one", path, (char*)0);
        _exit(127);
    }
    close(fd[1]);
    char b[128] = {0};
    ssize_t n = read(fd[0], b, sizeof b - 1);
    close(fd[0]);
    int st;
    waitpid(pid, &st, 0);
    if (n <= 0 || !WIFEXITED(st) || WEXITSTATUS(st) || sscanf(b, "%lf %lf", wall, cpu) != 2)
        return -1;
    return 0;
}

}  // namespace

int main(int argc, char** argv)
{
    if (argc == 3 && !strcmp(argv[1], "--one")) {
        double w, c;
        unsigned long s;
        long b;
        if (one(argv[2], &w, &c, &s, &b)) return 1;
        printf("%.9f %.9f\n", w, c);
        return 0;
    }
    if (argc < 2) {
        fprintf(stderr, "usage: ptexopen FILE.ptx [--reps N] [--warm]\n");
        return 2;
    }
    const char* path = argv[1];
    int reps = 9;
    bool warm = false;
    for (int i = 2; i < argc; i++) {
        if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--warm")) warm = true;
        else { fprintf(stderr, "usage: ptexopen FILE.ptx [--reps N] [--warm]\n"); return 2; }
    }
    if (reps < 1 || reps > 99) reps = 9;
    char self[4096];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) return 1;
    self[n] = 0;

    double w, c;
    unsigned long s;
    long bytes;
    if (one(path, &w, &c, &s, &bytes)) return 1;   // untimed: file into the page cache
    std::vector<double> fw, fc, wc;
    for (int r = 0; r < reps; r++) {
        if (fresh(self, path, &w, &c)) { fprintf(stderr, "child failed\n"); return 1; }
        fw.push_back(w);
        fc.push_back(c);
    }
    printf("ptexopen %s (Ptex %d.%d: PtexTexture::open, no cache, + getData of every face at "
           "level 0, %ld bytes): fresh process x %d: median wall %.3f ms, median cpu %.3f ms\n",
           path, PtexLibraryMajorVersion, PtexLibraryMinorVersion, bytes, reps,
           harness_median(fw) * 1e3, harness_median(fc) * 1e3);
    printf("  cpu ms per run:");
    for (size_t i = 0; i < fc.size(); i++) printf(" %.3f", fc[i] * 1e3);
    printf("\n");
    if (warm) {
        for (int r = 0; r < reps; r++) {
            if (one(path, &w, &c, &s, &bytes)) return 1;
            wc.push_back(c);
        }
        printf("  warm (same process) median cpu %.3f ms\n", harness_median(wc) * 1e3);
    }
    printf("RESULT fresh_cpu_ms=%.4f fresh_wall_ms=%.4f\n", harness_median(fc) * 1e3, harness_median(fw) * 1e3);
    return 0;
}
