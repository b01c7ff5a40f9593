/* tests/common/wait.c - see wait.h. */
#include "wait.h"

#include <dirent.h>
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

int64_t st_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

void st_sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR)
        ;
}

int st_wait_until(int (*cond)(void *arg), void *arg, int timeout_ms)
{
    int64_t deadline = st_now_ms() + timeout_ms;
    int step = 1;
    for (;;) {
        if (cond(arg))
            return 0;
        int64_t left = deadline - st_now_ms();
        if (left <= 0)
            return cond(arg) ? 0 : -1;
        st_sleep_ms(step < left ? step : (int)left);
        if (step < 20)
            step *= 2;
    }
}

int st_wait_readable(int fd, int timeout_ms)
{
    int64_t deadline = st_now_ms() + timeout_ms;
    for (;;) {
        struct pollfd p = {fd, POLLIN, 0};
        int64_t left = deadline - st_now_ms();
        int n = poll(&p, 1, left > 0 ? (int)left : 0);
        if (n > 0)
            return 1;
        if (n == 0 || errno != EINTR)
            return 0;
    }
}

typedef struct file_cond {
    const char *path, *needle;
} file_cond;

static int file_has(void *arg)
{
    const file_cond *fc = arg;
    FILE *f = fopen(fc->path, "r");
    if (!f)
        return 0;
    int found = fc->needle == NULL;
    char line[1024];
    while (!found && fgets(line, sizeof line, f))
        found = strstr(line, fc->needle) != NULL;
    fclose(f);
    return found;
}

int st_wait_file_has(const char *path, const char *needle, int timeout_ms)
{
    file_cond fc = {path, needle};
    return st_wait_until(file_has, &fc, timeout_ms);
}

/* 1 when every thread of the process is stopped, 0 when one is not (or the process is gone) */
static int all_stopped(void *arg)
{
    pid_t pid = *(const pid_t *)arg;
    char dir[64];
    snprintf(dir, sizeof dir, "/proc/%d/task", (int)pid);
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    int threads = 0, stopped = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.')
            continue;
        char path[320], buf[512];
        snprintf(path, sizeof path, "%s/%.200s/stat", dir, e->d_name);
        FILE *f = fopen(path, "r");
        if (!f)
            continue;              /* the thread exited meanwhile */
        size_t n = fread(buf, 1, sizeof buf - 1, f);
        fclose(f);
        buf[n] = 0;
        const char *end = strrchr(buf, ')');   /* "tid (comm) S ...": comm may hold ')' */
        threads++;
        stopped += end && (end[2] == 'T' || end[2] == 't');
    }
    closedir(d);
    return threads > 0 && stopped == threads;
}

int st_wait_stopped(pid_t pid, int timeout_ms)
{
    return st_wait_until(all_stopped, &pid, timeout_ms);
}
