#include "loopback_http.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <chrono>
#include <cmath>

namespace bgkmap::testing {

Socket::Socket(int port, double timeout_s) {
  fd_ = socket(AF_INET, SOCK_STREAM, 0);
  timeval timeout{static_cast<time_t>(timeout_s),
                  static_cast<suseconds_t>(std::fmod(timeout_s, 1.0) * 1e6)};
  setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  connected_ = connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
}

Socket::~Socket() { close(fd_); }

bool Socket::Send(const std::string& bytes) {
  size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return false;
    sent += static_cast<size_t>(n);
  }
  return true;
}

bool Socket::ReadSome(std::string* out) {
  char buf[65536];
  const ssize_t n = recv(fd_, buf, sizeof buf, 0);
  if (n <= 0) return false;
  out->append(buf, static_cast<size_t>(n));
  return true;
}

Reply ReadReply(Socket& s, std::string* buffer) {
  Reply r;
  size_t end;
  while ((end = buffer->find("\r\n\r\n")) == std::string::npos) {
    if (!s.ReadSome(buffer)) return r;
  }
  r.headers = buffer->substr(0, end);
  if (r.headers.rfind("HTTP/1.", 0) != 0) return r;
  r.status = std::stoi(r.headers.substr(9, 3));
  size_t length = 0;
  const size_t cl = r.headers.find("Content-Length: ");
  if (cl != std::string::npos) length = std::stoul(r.headers.substr(cl + 16));
  while (buffer->size() < end + 4 + length) {
    if (!s.ReadSome(buffer)) return Reply{};
  }
  r.body = buffer->substr(end + 4, length);
  buffer->erase(0, end + 4 + length);
  return r;
}

Reply Get(int port, const std::string& target, const std::string& method,
          const std::string& headers) {
  Socket s(port);
  if (!s.connected() || !s.Send(method + " " + target + " HTTP/1.1\r\nHost: localhost\r\n" +
                                headers + "Connection: close\r\n\r\n")) {
    return {};
  }
  std::string buffer;
  return ReadReply(s, &buffer);
}

int64_t MetricsSample(int port, const std::string& series) {
  const Reply reply = Get(port, "/metrics");
  const std::string line = "\n" + series + " ";
  const size_t at = reply.body.find(line);
  if (reply.status != 200 || at == std::string::npos) return -1;
  return std::stoll(reply.body.substr(at + line.size()));
}

std::optional<std::string> ReadEvent(Socket& s, std::string* buffer, const std::string& name,
                                     double seconds) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  for (;;) {
    const size_t at = buffer->find("event: " + name + "\ndata: ");
    if (at != std::string::npos) {
      const size_t start = at + name.size() + 14;
      const size_t end = buffer->find("\n\n", start);
      if (end != std::string::npos) {
        std::string data = buffer->substr(start, end - start);
        buffer->erase(0, end + 2);
        return data;
      }
    }
    if (std::chrono::steady_clock::now() > deadline || !s.ReadSome(buffer)) return std::nullopt;
  }
}

}  // namespace bgkmap::testing
