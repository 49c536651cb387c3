#pragma once
// The coordinator address every binary accepts (pf --coordinator, $PF_COORDINATOR, pf-worker
// --coordinator): HOST:PORT (a name, an IPv4 address or [IPv6]) with an explicit port, or a gRPC
// unix: socket target. gRPC itself would take "localhost" as localhost:443 and "nonsense" as a
// DNS name to retry forever, so a missing port is refused up front with a message.

#include <cctype>
#include <optional>
#include <string>

namespace pf {

// Empty if `address` is acceptable, else why not (one sentence, without the flag's name).
inline std::string CoordinatorAddressProblem(const std::string& address) {
  if (address.rfind("unix:", 0) == 0 || address.rfind("unix-abstract:", 0) == 0)
    return address.find(':') + 1 < address.size() ? "" : "a unix: target needs a socket path";
  std::string a = address;
  if (a.rfind("dns:///", 0) == 0) a = a.substr(7);
  const size_t colon = a.rfind(':');
  if (colon == std::string::npos || (a.front() == '[' && a.find(']') > colon))
    return "expected HOST:PORT (e.g. 127.0.0.1:7000); '" + address + "' has no port";
  const std::string host = a.substr(0, colon), port = a.substr(colon + 1);
  if (host.empty() || host == "[]") return "expected HOST:PORT; '" + address + "' has no host";
  if (port.empty() || port.size() > 5)
    return "expected HOST:PORT with a port 1..65535, got '" + address + "'";
  for (char c : port)
    if (!std::isdigit(static_cast<unsigned char>(c)))
      return "expected HOST:PORT with a numeric port, got '" + address + "'";
  const int p = std::stoi(port);
  if (p < 1 || p > 65535) return "port " + port + " is outside 1..65535";
  for (char c : host)
    if (std::isspace(static_cast<unsigned char>(c))) return "'" + address + "' contains a space";
  return "";
}

}  // namespace pf
