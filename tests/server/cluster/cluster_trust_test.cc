// NATS as a trust boundary: an attacker who reaches the NATS port (a raw nats.c client, no
// cluster key) publishes on the log's subjects, answers tile fetches and writes the membership
// bucket. Each attack runs against real nats-server processes and two in-process shards with a
// cluster key; the shards must answer exactly as a single server fed only the real scans.
// Without the key's checks (docs/scale-out.md, "Trust") every test here fails: the forged scan
// is integrated, the forged clear empties the map, the forged sequence 2^64-1 drops the robot's
// later scans, the forged reply answers empty tiles, the fake heartbeats make queries
// UNAVAILABLE.
#include <gtest/gtest.h>
#include <nats/nats.h>

#include <atomic>
#include <chrono>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/v1/cluster.pb.h"
#include "bgkmap/v1/types.pb.h"
#include "cluster_support.h"
#include "loopback_http.h"
#include "nats_cluster.h"
#include "test_pki.h"

namespace bgkmap::testing {
namespace {

// A NATS client with no cluster key: what anyone who reaches the NATS port can be.
class Attacker {
 public:
  explicit Attacker(const std::string& url) {
    EXPECT_EQ(natsConnection_ConnectTo(&nc_, url.c_str()), NATS_OK);
    EXPECT_EQ(natsConnection_JetStream(&js_, nc_, nullptr), NATS_OK);
  }
  ~Attacker() {
    if (sub_ != nullptr) natsSubscription_Destroy(sub_);
    jsCtx_Destroy(js_);
    natsConnection_Destroy(nc_);
  }

  // The log's last scan entry as stored: its payload and its headers (the stream hands out
  // every robot's scans to anyone who may read it).
  void CopyLastScan(std::string* payload, std::map<std::string, std::string>* headers) {
    natsMsg* msg = nullptr;
    jsErrCode jerr = static_cast<jsErrCode>(0);
    ASSERT_EQ(js_GetLastMsg(&msg, js_, "BGKMAP_LOG", "bgkmap.log.scan", nullptr, &jerr), NATS_OK);
    payload->assign(natsMsg_GetData(msg), static_cast<size_t>(natsMsg_GetDataLength(msg)));
    const char** keys = nullptr;
    int count = 0;
    ASSERT_EQ(natsMsgHeader_Keys(msg, &keys, &count), NATS_OK);
    for (int i = 0; i < count; ++i) {
      const char* value = nullptr;
      natsMsgHeader_Get(msg, keys[i], &value);
      (*headers)[keys[i]] = value == nullptr ? "" : value;
    }
    free(static_cast<void*>(keys));
    natsMsg_Destroy(msg);
  }

  // Stores `payload` with `headers` in the log (JetStream acks it: the entry is in the log).
  void Publish(const std::string& subject, const std::string& payload,
               const std::map<std::string, std::string>& headers) {
    natsMsg* msg = nullptr;
    ASSERT_EQ(natsMsg_Create(&msg, subject.c_str(), nullptr, payload.data(),
                             static_cast<int>(payload.size())),
              NATS_OK);
    for (const auto& [k, v] : headers)
      ASSERT_EQ(natsMsgHeader_Set(msg, k.c_str(), v.c_str()), NATS_OK);
    jsPubAck* ack = nullptr;
    jsErrCode jerr = static_cast<jsErrCode>(0);
    ASSERT_EQ(js_PublishMsg(&ack, js_, msg, nullptr, &jerr), NATS_OK) << static_cast<int>(jerr);
    jsPubAck_Destroy(ack);
    natsMsg_Destroy(msg);
  }

  // Answers every tile fetch at once with an empty reply (no tiles, no error).
  void AnswerFetchesWithNothing() {
    ASSERT_EQ(natsConnection_Subscribe(
                  &sub_, nc_, "bgkmap.tiles.>",
                  [](natsConnection* nc, natsSubscription*, natsMsg* msg, void*) {
                    if (natsMsg_GetReply(msg) != nullptr) {
                      natsConnection_Publish(nc, natsMsg_GetReply(msg), "", 0);
                    }
                    natsMsg_Destroy(msg);
                  },
                  nullptr),
              NATS_OK);
    ASSERT_EQ(natsConnection_Flush(nc_), NATS_OK);
  }

  // The partitions recorded in the membership bucket (their names).
  std::vector<std::string> Partitions() {
    kvStore* kv = nullptr;
    EXPECT_EQ(js_KeyValue(&kv, js_, "bgkmap_partitions"), NATS_OK);
    kvKeysList keys;
    std::vector<std::string> out;
    if (kvStore_Keys(&keys, kv, nullptr) == NATS_OK) {
      for (int i = 0; i < keys.Count; ++i) out.push_back(keys.Keys[i]);
      kvKeysList_Destroy(&keys);
    }
    kvStore_Destroy(kv);
    return out;
  }

  // Puts `count` node names in the membership bucket, again every 200 ms, until `stop`.
  void FakeHeartbeats(int count, const std::atomic<bool>& stop) {
    kvStore* kv = nullptr;
    ASSERT_EQ(js_KeyValue(&kv, js_, "bgkmap_nodes"), NATS_OK);
    while (!stop) {
      for (int i = 0; i < count; ++i) {
        uint64_t rev = 0;
        const std::string name = "intruder" + std::to_string(i);
        kvStore_PutString(&rev, kv, name.c_str(), "alive");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    kvStore_Destroy(kv);
  }

 private:
  natsConnection* nc_ = nullptr;
  jsCtx* js_ = nullptr;
  natsSubscription* sub_ = nullptr;
};

// Two shards holding the street's scans of two robots, and the single server fed the same.
struct TwoShards {
  TempDir dir{"bgkmap_cluster_trust"};
  NatsCluster nats{1, dir.str()};
  std::vector<OwnedScan> scans = TwoRobots();
  Reference ref{scans};
  std::unique_ptr<ServerFixture> a, b;
  TwoShards() {
    EXPECT_TRUE(nats.started());
    ServerConfig ca = NodeConfig(nats.urls(), "a");
    ca.metrics_address = "127.0.0.1:0";
    a = std::make_unique<ServerFixture>(ca);
    b = std::make_unique<ServerFixture>(NodeConfig(nats.urls(), "b"));
  }
  // Shard a's bgkmap_cluster_rejected_total{kind=...} (-1: not in /metrics).
  int64_t Refused(const std::string& kind) {
    return MetricsSample(a->server().http_port(),
                         "bgkmap_cluster_rejected_total{kind=\"" + kind + "\"}");
  }
};

TEST(ClusterTrustTest, AForgedScanIsNotApplied) {
  TwoShards c;
  InsertAll(c.a->client(), c.scans, 0, c.scans.size());
  Attacker attacker(c.nats.url(0));
  std::string payload;
  std::map<std::string, std::string> headers;
  attacker.CopyLastScan(&payload, &headers);
  // A real scan's bytes again, as a new robot's first scan (so no duplicate rule stops it).
  headers["Bgkmap-Robot"] = "intruder";
  headers["Bgkmap-Sequence"] = "1";
  headers["Nats-Msg-Id"] = "intruder/1";
  attacker.Publish("bgkmap.log.scan", payload, headers);
  // A query reads the log up to its end: the forged entry was read before it answers.
  EXPECT_TRUE(SameAnswers(c.a->client(), c.ref));
  EXPECT_TRUE(SameAnswers(c.b->client(), c.ref));
  EXPECT_GE(c.Refused("log_entry"), 1);
}

TEST(ClusterTrustTest, AForgedClearIsNotApplied) {
  TwoShards c;
  InsertAll(c.a->client(), c.scans, 0, c.scans.size());
  Attacker attacker(c.nats.url(0));
  v1::CellBox everything;
  everything.set_min_x(-1000000);
  everything.set_min_y(-1000000);
  everything.set_max_x(1000000);
  everything.set_max_y(1000000);
  // A real entry's partitions header (a shard applies a clear to every partition it holds).
  std::string unused;
  std::map<std::string, std::string> scan_headers;
  attacker.CopyLastScan(&unused, &scan_headers);
  attacker.Publish("bgkmap.log.clear", everything.SerializeAsString(),
                   {{"Bgkmap-Partitions", scan_headers["Bgkmap-Partitions"]},
                    {"Bgkmap-Cells", "-1000000 -1000000 1000000 1000000"}});
  EXPECT_TRUE(SameAnswers(c.a->client(), c.ref));
  EXPECT_TRUE(SameAnswers(c.b->client(), c.ref));
  EXPECT_GE(c.Refused("log_entry"), 1);
}

TEST(ClusterTrustTest, AForgedLastSequenceDoesNotLockARobotOut) {
  TwoShards c;
  const size_t half = c.scans.size() / 2;
  InsertAll(c.a->client(), c.scans, 0, half);
  Attacker attacker(c.nats.url(0));
  std::string payload;
  std::map<std::string, std::string> headers;
  attacker.CopyLastScan(&payload, &headers);
  headers["Bgkmap-Robot"] = "r1";
  headers["Bgkmap-Sequence"] = "18446744073709551615";
  headers["Nats-Msg-Id"] = "r1/18446744073709551615";
  attacker.Publish("bgkmap.log.scan", payload, headers);
  // r1's next real scans are acknowledged APPLIED (InsertAll checks): they must be applied.
  InsertAll(c.b->client(), c.scans, half, c.scans.size());
  EXPECT_TRUE(SameAnswers(c.a->client(), c.ref));
  EXPECT_TRUE(SameAnswers(c.b->client(), c.ref));
  EXPECT_GE(c.Refused("log_entry"), 1);
}

TEST(ClusterTrustTest, AForgedTileFetchReplyIsIgnored) {
  TwoShards c;
  InsertAll(c.a->client(), c.scans, 0, c.scans.size());
  Attacker attacker(c.nats.url(0));
  attacker.AnswerFetchesWithNothing();
  EXPECT_TRUE(SameAnswers(c.a->client(), c.ref));
  EXPECT_TRUE(SameAnswers(c.b->client(), c.ref));
  EXPECT_GE(c.Refused("tile_reply"), 1);
  EXPECT_EQ(c.Refused("log_entry"), 0);
}

TEST(ClusterTrustTest, FakeHeartbeatsDoNotTakePartitions) {
  TwoShards c;
  InsertAll(c.a->client(), c.scans, 0, c.scans.size());
  Attacker attacker(c.nats.url(0));
  // Thirty fake nodes for long enough that the shards would have handed them their partitions
  // (a lease to see them, two leases of grace; lease_s is 1 here), and on while querying.
  std::atomic<bool> stop{false};
  std::thread fake([&] { attacker.FakeHeartbeats(30, stop); });
  std::this_thread::sleep_for(std::chrono::seconds(5));
  EXPECT_TRUE(SameAnswers(c.a->client(), c.ref));
  EXPECT_TRUE(SameAnswers(c.b->client(), c.ref));
  stop = true;
  fake.join();
  EXPECT_GE(c.Refused("membership"), 30);
}

// A forged checkpoint for every partition: empty, as of a log sequence far past the log's end.
// Believed, a takeover would restore it and serve empty partitions (and a trim would drop the
// whole log); refused, the partitions are rebuilt from the log. Mutation checked by hand:
// ReadManifest without the HMAC check makes the answers after the takeover differ.
TEST(ClusterTrustTest, AForgedCheckpointIsNotRestored) {
  TwoShards c;
  InsertAll(c.a->client(), c.scans, 0, c.scans.size());
  Attacker attacker(c.nats.url(0));
  v1::CheckpointManifest forged;
  forged.set_log_sequence(1000000000);
  forged.set_tiles(0);
  const std::vector<std::string> partitions = attacker.Partitions();
  ASSERT_FALSE(partitions.empty());
  for (const std::string& p : partitions) {
    attacker.Publish("bgkmap.ckpt." + p + ".manifest", forged.SerializeAsString(), {});
  }
  // Shard a leaves: b takes its partitions over, from their newest checkpoints.
  c.a.reset();
  EXPECT_TRUE(EventuallySameAnswers(c.b->client(), c.ref, std::chrono::steady_clock::now()));
}

// cluster.nats_tls: NATS servers that demand TLS and a client certificate signed by their CA.
// Shards with the CA and a client certificate ingest and answer as one server; a client without
// a certificate is not let in, nor is a shard without cluster.nats_tls (named in its error).
TEST(ClusterTrustTest, ShardsReachNatsOverTlsWithAClientCertificate) {
  TempDir dir("bgkmap_cluster_tls");
  ASSERT_TRUE(MakeTestPki(dir.str()));
  NatsCluster nats(1, dir.str(), {dir.str(), /*verify_clients=*/true});
  ASSERT_TRUE(nats.started());
  natsConnection* plain = nullptr;
  EXPECT_NE(natsConnection_ConnectTo(&plain, nats.url(0).c_str()), NATS_OK);
  natsConnection_Destroy(plain);

  ServerConfig bare = NodeConfig(nats.urls(), "bare");
  Result<std::unique_ptr<MapServer>> refused = MapServer::Start(bare);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("cluster.nats: cannot connect to"), std::string::npos)
      << refused.status().message();

  auto tls_node = [&](const std::string& name) {
    ServerConfig c = NodeConfig(nats.urls(), name);
    c.cluster.nats_tls.ca_file = dir.Sub("ca.pem");
    c.cluster.nats_tls.cert_file = dir.Sub("client.pem");
    c.cluster.nats_tls.key_file = dir.Sub("client.key");
    return c;
  };
  // cluster.nats_credentials is read when the shard connects: a missing file is named.
  ServerConfig creds = tls_node("creds");
  creds.cluster.nats_credentials = dir.Sub("missing.creds");
  Result<std::unique_ptr<MapServer>> no_creds = MapServer::Start(creds);
  ASSERT_FALSE(no_creds.ok());
  EXPECT_NE(no_creds.status().message().find("missing.creds"), std::string::npos)
      << no_creds.status().message();

  const std::vector<OwnedScan> scans = TwoRobots();
  Reference ref(scans);
  ServerFixture a(tls_node("a")), b(tls_node("b"));
  InsertAll(a.client(), scans, 0, scans.size());
  EXPECT_TRUE(SameAnswers(a.client(), ref));
  EXPECT_TRUE(SameAnswers(b.client(), ref));
}

}  // namespace
}  // namespace bgkmap::testing
