// A plain HTTP/1.1 client for the tests of bgkmapd's HTTP port: a loopback socket, one response
// read at a time (Content-Length framed), and the events of an /events stream.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace bgkmap::testing {

// A connected loopback socket with a receive timeout, closed on destruction.
class Socket {
 public:
  explicit Socket(int port, double timeout_s = 15);
  ~Socket();
  Socket(const Socket&) = delete;
  Socket& operator=(const Socket&) = delete;
  bool connected() const { return connected_; }
  bool Send(const std::string& bytes);
  // Appends what arrives to `out`; false on close, error or timeout.
  bool ReadSome(std::string* out);

 private:
  int fd_ = -1;
  bool connected_ = false;
};

struct Reply {
  int status = 0;  // 0: no answer
  std::string headers;
  std::string body;
};

// Reads one response (Content-Length framed) from `s`, `buffer` holding bytes already read.
Reply ReadReply(Socket& s, std::string* buffer);

// `method target` on a connection of its own, with `headers` ("Name: value\r\n" lines) added.
Reply Get(int port, const std::string& target, const std::string& method = "GET",
          const std::string& headers = "");

// The value of the sample `series` (a metric's name, with its labels if it has any) in GET
// /metrics on `port`; -1 when the scrape fails or does not hold it.
int64_t MetricsSample(int port, const std::string& series);

// Reads an event stream until `event: name` arrives or `seconds` pass; the event's data line.
std::optional<std::string> ReadEvent(Socket& s, std::string* buffer, const std::string& name,
                                     double seconds);

}  // namespace bgkmap::testing
