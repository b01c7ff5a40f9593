/* tests/common/wait.h - waiting for an event instead of sleeping a fixed time.
 *
 * Owns: a monotonic clock in ms, a poll loop with a deadline (st_wait_until) and the usual
 * conditions built on it (a socket readable, a file holding a line). Tests wait for what they
 * need - a STATS counter (daemon_client.h), a file, a process state - so they are as quick as
 * the machine allows and do not fail on a slow one. Does not own: what is waited for.
 *
 * st_sleep_ms is kept for the few waits that are themselves the thing under test (a timeout
 * that must elapse, a kill at a random moment); each caller says why in a comment.
 */
#ifndef ST_WAIT_H
#define ST_WAIT_H

#include <stdint.h>
#include <sys/types.h>

/* CLOCK_MONOTONIC in milliseconds. */
int64_t st_now_ms(void);

/* Sleeps ms milliseconds (restarted after a signal). Only for a delay that is under test. */
void st_sleep_ms(int ms);

/* Calls cond(arg) until it returns nonzero or timeout_ms have passed, sleeping 1 ms at first
 * and up to 20 ms between calls. Returns 0 when the condition held, -1 on timeout (cond is
 * called once more at the deadline). */
int st_wait_until(int (*cond)(void *arg), void *arg, int timeout_ms);

/* 1 when fd has something to read (data, EOF or an error) within timeout_ms, else 0. */
int st_wait_readable(int fd, int timeout_ms);

/* Waits until the file at path exists and, when needle is not NULL, holds a line containing
 * needle. 0 or -1 on timeout. */
int st_wait_file_has(const char *path, const char *needle, int timeout_ms);

/* Waits until every thread of process pid is stopped (state T or t in /proc/<pid>/task/
 * <tid>/stat). kill(SIGSTOP) returns once the signal is queued; the process stops only when
 * one of its threads takes the signal, which on a loaded machine can be many milliseconds
 * later - meanwhile the others go on serving. 0, or -1 on timeout or when pid is gone. */
int st_wait_stopped(pid_t pid, int timeout_ms);

#endif
