#include "nats_cluster.h"

#include <arpa/inet.h>
#include <nats/nats.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace bgkmap::testing {

int FreeLoopbackPort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof addr;
  int port = 0;
  if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
      getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
    port = ntohs(addr.sin_port);
  }
  close(fd);
  return port;
}

NatsCluster::NatsCluster(int servers, const std::string& dir, const NatsServerSecurity& security)
    : dir_(dir), security_(security) {
  for (int i = 0; i < servers; ++i) {
    client_ports_.push_back(FreeLoopbackPort());
    route_ports_.push_back(FreeLoopbackPort());
  }
  servers_.resize(servers);
  started_ = true;
  for (int i = 0; i < servers; ++i) started_ = Launch(i) && started_;
}

std::string NatsCluster::url(int i) const {
  return "nats://127.0.0.1:" + std::to_string(client_ports_[i]);
}

std::string NatsCluster::urls() const {
  std::string out;
  for (size_t i = 0; i < client_ports_.size(); ++i) {
    if (!out.empty()) out += ',';
    out += url(static_cast<int>(i));
  }
  return out;
}

bool NatsCluster::Launch(int i) {
  std::string name = "n";
  name += std::to_string(i);
  const std::string store = dir_ + "/" + name;
  std::filesystem::create_directories(store);
  const std::string conf = dir_ + "/" + name + ".conf";
  {
    std::ofstream out(conf);
    out << "server_name: " << name << "\n"
        << "listen: 127.0.0.1:" << client_ports_[i] << "\n"
        << "max_payload: 8MB\n"
        << "jetstream { store_dir: \"" << store << "\", max_memory_store: 64MB }\n";
    if (!security_.tls_dir.empty()) {
      const std::string& t = security_.tls_dir;
      out << "tls { cert_file: \"" << t << "/server.pem\", key_file: \"" << t
          << "/server.key\", ca_file: \"" << t
          << "/ca.pem\", verify: " << (security_.verify_clients ? "true" : "false") << " }\n";
    }
    if (client_ports_.size() > 1) {
      out << "cluster { name: bgkmap_test, listen: 127.0.0.1:" << route_ports_[i] << ", routes: [";
      const char* sep = "";
      for (size_t j = 0; j < route_ports_.size(); ++j) {
        if (static_cast<int>(j) == i) continue;
        out << sep << "nats-route://127.0.0.1:" << route_ports_[j];
        sep = ", ";
      }
      out << "] }\n";
    }
  }
  // A clustered JetStream serves once a meta leader is elected.
  const std::string ready = client_ports_.size() > 1
                                ? "JetStream cluster new metadata leader|Server is ready"
                                : "Server is ready";
  servers_[i] = std::make_unique<BgkmapdProcess>(
      std::vector<std::string>{"/usr/sbin/nats-server", "-c", conf}, ready);
  if (!servers_[i]->started()) {
    for (const std::string& line : servers_[i]->Log()) std::fprintf(stderr, "%s\n", line.c_str());
  }
  return servers_[i]->started();
}

void NatsCluster::Kill(int i) {
  servers_[i]->Signal(SIGKILL);
  servers_[i]->Wait(10);
}

void NatsCluster::Signal(int i, int signal) { servers_[i]->Signal(signal); }

bool NatsCluster::Restart(int i) { return Launch(i); }

namespace {

// Server `name` is the leader or a current replica of every replicated stream in `streams`.
bool HoldsEveryStream(const jsStreamInfoList& streams, const std::string& name) {
  for (int s = 0; s < streams.Count; ++s) {
    const jsClusterInfo* cluster = streams.List[s]->Cluster;
    if (cluster == nullptr || cluster->ReplicasLen == 0) continue;
    if (cluster->Leader != nullptr && name == cluster->Leader) continue;
    for (int r = 0; r < cluster->ReplicasLen; ++r) {
      const jsPeerInfo* peer = cluster->Replicas[r];
      if (name == peer->Name && (!peer->Current || peer->Offline || peer->Lag != 0)) return false;
    }
  }
  return true;
}

}  // namespace

bool NatsCluster::WaitCaughtUp(int i, double seconds) {
  std::string others;
  for (size_t j = 0; j < client_ports_.size(); ++j) {
    if (static_cast<int>(j) == i) continue;
    if (!others.empty()) others.push_back(',');
    others.append(url(static_cast<int>(j)));
  }
  std::string name = "n";  // (built in two steps: GCC 12's -Wrestrict misfires on "n" + string)
  name += std::to_string(i);
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  bool caught_up = false;
  while (!caught_up && std::chrono::steady_clock::now() < until) {
    natsConnection* conn = nullptr;
    jsCtx* js = nullptr;
    jsStreamInfoList* streams = nullptr;
    if (natsConnection_ConnectTo(&conn, others.c_str()) == NATS_OK &&
        natsConnection_JetStream(&js, conn, nullptr) == NATS_OK &&
        js_Streams(&streams, js, nullptr, nullptr) == NATS_OK) {
      caught_up = HoldsEveryStream(*streams, name);
    }
    if (streams != nullptr) jsStreamInfoList_Destroy(streams);
    jsCtx_Destroy(js);
    natsConnection_Destroy(conn);
    if (!caught_up) usleep(200 * 1000);
  }
  return caught_up;
}

}  // namespace bgkmap::testing
