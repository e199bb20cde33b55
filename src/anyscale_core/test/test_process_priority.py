"""set_own_nice reaches every thread of the process, in a child process so that this one keeps
its priority."""
import os
import subprocess
import sys
import textwrap

CHILD = textwrap.dedent("""
    import os, threading, time
    from anyscale_core.process_priority import set_own_nice, thread_ids

    def thread_nices():
        nices = []
        for tid in thread_ids():
            try:
                nices.append(os.getpriority(os.PRIO_PROCESS, tid))
            except ProcessLookupError:
                pass        # the thread (the one that asked) ended meanwhile
        return nices

    threading.Thread(target=time.sleep, args=(5,), daemon=True).start()
    error = set_own_nice(int(sys.argv[1]))
    late = []
    t = threading.Thread(target=lambda: late.append(thread_nices()))
    t.start(); t.join()
    print(error, sorted(set(thread_nices())), sorted(set(late[0])))
""")


def run_child(nice, unprivileged=False):
    # As root, the unprivileged case runs as nobody, as a user without CAP_SYS_NICE would.
    demote = (lambda: os.setuid(65534)) if unprivileged and os.geteuid() == 0 else None
    done = subprocess.run([sys.executable, "-c", "import sys\n" + CHILD, str(nice)],
                          capture_output=True, text=True, timeout=30, preexec_fn=demote)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_every_thread_and_the_ones_started_later_get_the_nice():
    base = os.getpriority(os.PRIO_PROCESS, 0)
    target = min(base + 4, 19)      # raising a nice value needs no privilege
    assert run_child(target) == f"None [{target}] [{target}]"


def test_a_refused_raise_says_why():
    assert run_child(-5, unprivileged=True).startswith("setpriority(")
