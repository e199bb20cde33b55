"""Service calls that outlive a roscore restart: each service's URI as the master last gave it,
used while the master cannot give it.

rospy asks the master for a service's URI at every call (ServiceProxy._get_service_uri). A
master that is gone, or one that restarted and has not yet been given back the old one's
registrations (the master keeper), answers none, although the agents' services run on as
before at the same URI. The decision node renews the remote scales' leases that way, every
tick: for as long as the master could not answer, no renewal reached the laptop's agent, and
when that outlasted a lease (3 s) the agent ended AMCL and AR there."""
import threading
from typing import Dict, Optional

import rospy


class ServiceUris:
    """The URI each service had when the master last gave it, shared across threads."""

    def __init__(self):
        self._uris: Dict[str, str] = {}
        self._lock = threading.Lock()

    def found(self, service: str, uri: str):
        with self._lock:
            self._uris[service] = uri

    def last(self, service: str) -> Optional[str]:
        with self._lock:
            return self._uris.get(service)


class RememberingServiceProxy(rospy.ServiceProxy):
    """A rospy.ServiceProxy that takes the master's answer when there is one and the last one
    when there is not. A stale URI costs one refused connection, the same ServiceException the
    call would have raised without it."""

    def __init__(self, name: str, service_class, uris: ServiceUris):
        super().__init__(name, service_class)
        self._uris = uris

    def _get_service_uri(self, request):
        try:
            uri = super()._get_service_uri(request)
        except rospy.ServiceException:
            uri = None
        if uri:
            self._uris.found(self.resolved_name, uri)
            return uri
        last = self._uris.last(self.resolved_name)
        if last is None:
            raise rospy.ServiceException(f"service [{self.resolved_name}] unavailable: the master "
                                         f"cannot tell where it is and it was never found")
        return last
