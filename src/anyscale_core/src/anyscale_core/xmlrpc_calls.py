"""XML-RPC to the ROS master and to a node's API with a timeout, ROS-free.

xmlrpc.client waits for as long as TCP does: a node behind a partitioned link, or a stopped
one (SIGSTOP: its socket still accepts the connection, nothing answers), would hold the
caller for minutes."""
import xmlrpc.client


class TimeoutTransport(xmlrpc.client.Transport):
    def __init__(self, timeout_s: float):
        super().__init__()
        self._timeout_s = timeout_s

    def make_connection(self, host):
        conn = super().make_connection(host)
        conn.timeout = self._timeout_s
        return conn


def proxy(uri: str, timeout_s: float) -> xmlrpc.client.ServerProxy:
    """A proxy for one thread's calls to `uri`, each given up after timeout_s."""
    return xmlrpc.client.ServerProxy(uri, transport=TimeoutTransport(timeout_s),
                                     allow_none=True)
