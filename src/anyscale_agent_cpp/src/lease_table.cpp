// Lease bookkeeping: grant, renew, expire.
#include "anyscale_agent_cpp/lease_table.h"

#include <algorithm>

namespace anyscale_agent
{

void LeaseTable::grant(const std::string& node, double now, double duration_s)
{
  if (duration_s <= 0.0)
    expiry_.erase(node);
  else
    expiry_[node] = now + duration_s;
}

bool LeaseTable::renew(const std::string& node, double now, double duration_s)
{
  auto it = expiry_.find(node);
  if (it == expiry_.end() || duration_s <= 0.0)
    return false;
  it->second = std::max(it->second, now + duration_s);
  return true;
}

void LeaseTable::remove(const std::string& node)
{
  expiry_.erase(node);
}

std::vector<std::string> LeaseTable::takeExpired(double now)
{
  std::vector<std::string> out;
  for (auto it = expiry_.begin(); it != expiry_.end();)
  {
    if (it->second <= now)
    {
      out.push_back(it->first);
      it = expiry_.erase(it);
    }
    else
    {
      ++it;
    }
  }
  return out;
}

std::optional<double> LeaseTable::expiry(const std::string& node) const
{
  const auto it = expiry_.find(node);
  if (it == expiry_.end())
    return std::nullopt;
  return it->second;
}

}  // namespace anyscale_agent
