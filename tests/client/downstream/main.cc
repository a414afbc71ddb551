// Connects to a bgkmapd and prints its map version; exits 0 also when no server answers.
#include <bgkmap/client/client.h>

#include <iostream>

int main(int argc, char** argv) {
  bgkmap::ClientOptions options;
  options.timeout = std::chrono::seconds(2);
  bgkmap::Client client(argc > 1 ? argv[1] : "127.0.0.1:50051", options);
  const bgkmap::RpcResult<bgkmap::MapInfo> info = client.Info();
  if (info.ok()) {
    std::cout << "map version " << info->map_version << "\n";
    return 0;
  }
  std::cout << info.status().ToString() << "\n";
  return info.status().code() == bgkmap::RpcCode::kUnavailable ? 0 : 1;
}
