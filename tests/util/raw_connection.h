#pragma once
// A raw TCP connection to 127.0.0.1:PORT, for requests no HTTP client would send (huge or slow
// heads, bodies nobody asked for). Sends and receives give up after 5 s.
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <string>

namespace pf::test_util {

// Connects the TCP socket `fd` to 127.0.0.1:PORT, its sends and receives giving up after 5 s.
inline bool ConnectToLoopback(int fd, int port) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(uint16_t(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const timeval five{5, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &five, sizeof(five));
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &five, sizeof(five));
  return ::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0;
}

class RawConnection {
 public:
  explicit RawConnection(int port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    connected_ = ConnectToLoopback(fd_, port);
  }
  ~RawConnection() { ::close(fd_); }
  RawConnection(const RawConnection&) = delete;
  RawConnection& operator=(const RawConnection&) = delete;

  bool connected() const { return connected_; }
  bool Send(const std::string& bytes) {
    return ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) == ssize_t(bytes.size());
  }
  // Sends up to `total` copies of `byte` in 1 MiB pieces; returns how many the peer took before
  // the connection failed (or all of them).
  size_t SendMany(char byte, size_t total) {
    const std::string piece(size_t(1) << 20, byte);
    size_t sent = 0;
    while (sent < total) {
      const ssize_t n = ::send(fd_, piece.data(), std::min(piece.size(), total - sent), MSG_NOSIGNAL);
      if (n <= 0) break;
      sent += size_t(n);
    }
    return sent;
  }
  // What arrives until the peer closes, 4 KiB are in or `seconds` pass.
  std::string Receive(double seconds = 5) {
    const timeval t{time_t(seconds), suseconds_t((seconds - time_t(seconds)) * 1e6)};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &t, sizeof(t));
    std::string out;
    char buf[4096];
    while (out.size() < sizeof(buf)) {
      const ssize_t n = ::recv(fd_, buf, sizeof(buf) - out.size(), 0);
      if (n <= 0) break;
      out.append(buf, size_t(n));
    }
    return out;
  }
  // Exactly `n` bytes, or fewer if the peer closes or `seconds` pass first.
  std::string ReceiveExactly(size_t n, double seconds = 5) {
    const timeval t{time_t(seconds), suseconds_t((seconds - time_t(seconds)) * 1e6)};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &t, sizeof(t));
    std::string out(n, '\0');
    size_t got = 0;
    while (got < n) {
      const ssize_t r = ::recv(fd_, out.data() + got, n - got, 0);
      if (r <= 0) break;
      got += size_t(r);
    }
    out.resize(got);
    return out;
  }
  // True if the peer has closed the connection (a read returns end of file or a reset).
  bool ClosedByPeer(double seconds) {
    const timeval t{time_t(seconds), suseconds_t((seconds - time_t(seconds)) * 1e6)};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &t, sizeof(t));
    char buf[4096];
    for (;;) {
      const ssize_t n = ::recv(fd_, buf, sizeof(buf), 0);
      if (n == 0) return true;
      if (n < 0) return errno != EAGAIN && errno != EWOULDBLOCK;
    }
  }

 private:
  int fd_;
  bool connected_ = false;
};

}  // namespace pf::test_util
