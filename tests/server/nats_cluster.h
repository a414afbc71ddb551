// Real nats-server processes with JetStream on loopback ports for the cluster tests: one
// server, or a cluster of several (routes between them, so streams can have replicas).
// Each server can be killed (SIGKILL) and restarted on the same ports and store.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bgkmapd_process.h"

namespace bgkmap::testing {

// What each server of a NatsCluster demands of its clients.
struct NatsServerSecurity {
  // A directory of MakeTestPki's files: clients must use TLS (server.pem, server.key) and, with
  // `verify_clients`, present a certificate signed by ca.pem.
  std::string tls_dir;
  bool verify_clients = false;
};

class NatsCluster {
 public:
  // `dir`: where configs and JetStream stores go (one subdirectory per server).
  NatsCluster(int servers, const std::string& dir, const NatsServerSecurity& security = {});
  // Every server is up and, for a cluster, JetStream has a meta leader.
  bool started() const { return started_; }
  // Every client URL, comma-separated (what cluster.nats takes).
  std::string urls() const;
  std::string url(int i) const;
  void Kill(int i);
  void Signal(int i, int signal);  // e.g. SIGSTOP: a server that holds its connections, silent
  bool Restart(int i);             // true once the server is up again
  // Waits until server i holds every stream it replicates up to date (the stream's leader, or a
  // replica JetStream reports current with no lag), asking the cluster through the other
  // servers; false after `seconds`. A restarted server is needed for a quorum only once this holds.
  bool WaitCaughtUp(int i, double seconds);

 private:
  bool Launch(int i);
  std::string dir_;
  NatsServerSecurity security_;
  std::vector<int> client_ports_, route_ports_;
  std::vector<std::unique_ptr<BgkmapdProcess>> servers_;
  bool started_ = false;
};

// A free TCP port on 127.0.0.1 (bound, then released).
int FreeLoopbackPort();

}  // namespace bgkmap::testing
