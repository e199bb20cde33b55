// Leases of nodes started on a remote scale: who must be stopped when renewals stop (no ROS).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace anyscale_agent
{

// Times are seconds on a monotonic clock supplied by the caller, so a jump of the wall clock
// (NTP after a partition heals) can neither expire nor extend a lease.
class LeaseTable
{
public:
  // The lease of a new instance of `node`, ending at now + duration_s; duration_s <= 0: none,
  // the instance runs until stopped. Only for an instance just started: a running one's lease
  // only ever moves later (renew), or a request could end it early or take it away.
  void grant(const std::string& node, double now, double duration_s);

  // Moves the end of an existing lease to now + duration_s if that is later, never earlier;
  // false if `node` holds none (it ran without a lease, or is gone): none is imposed.
  bool renew(const std::string& node, double now, double duration_s);

  void remove(const std::string& node);

  // Nodes whose lease ended at or before `now`; they are removed from the table.
  std::vector<std::string> takeExpired(double now);

  // When the lease of `node` ends; nullopt if it has none.
  std::optional<double> expiry(const std::string& node) const;

private:
  std::map<std::string, double> expiry_;
};

}  // namespace anyscale_agent
