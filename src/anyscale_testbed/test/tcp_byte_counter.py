"""A TCP byte counter for the test beds' network tests: a listener started on one scale end
counts what a client on another sends it, and the client times the transfer."""
import sys
import time

from anyscale_testbed.two_scale_testbed import run

# argv: address, port. Answers each connection with the number of bytes it received.
LISTENER = """
import socket, sys
s = socket.socket(); s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
s.bind((sys.argv[1], int(sys.argv[2]))); s.listen(4); print("ready", flush=True)
while True:
    c, _ = s.accept(); n = 0
    while True:
        b = c.recv(65536)
        if not b: break
        n += len(b)
    c.sendall(str(n).encode()); c.close()
"""

# argv: address, port, bytes to send, timeout in s. Prints the count received and the seconds.
CLIENT = """
import socket, sys, time
t = time.monotonic()
s = socket.create_connection((sys.argv[1], int(sys.argv[2])), timeout=float(sys.argv[4]))
s.sendall(b"x" * int(sys.argv[3])); s.shutdown(socket.SHUT_WR)
print(s.recv(64).decode(), time.monotonic() - t)
"""


def start_listener(bed, scale, address, port, log_path):
    """The listener on `scale` of the bed, once it listens (its log says "ready")."""
    listener = bed.start(scale, [sys.executable, "-u", "-c", LISTENER, address, str(port)],
                         log_path=str(log_path))
    for _ in range(50):
        if "ready" in log_path.read_text():
            break
        time.sleep(0.1)
    return listener


def send_bytes(namespace, address, port, size, timeout_s=30):
    """`size` bytes from the network namespace `namespace` to the listener at address:port:
    (bytes it received, seconds), or (None, None) if they could not be sent."""
    done = run(["ip", "netns", "exec", namespace, sys.executable, "-c", CLIENT, address,
                str(port), str(size), str(timeout_s)], check=False)
    if done.returncode != 0:
        return None, None
    received, seconds = done.stdout.split()
    return int(received), float(seconds)
