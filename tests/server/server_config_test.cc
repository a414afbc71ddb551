// bgkmapd configuration: YAML with engine keys and a server section, overrides, printing.
#include "bgkmap/server/server_config.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

namespace bgkmap {
namespace {

TEST(ServerConfigTest, ReadsEngineKeysAndServerSection) {
  const YAML::Node doc = YAML::Load(R"(
resolution: 0.2
tile_size: 32
server:
  listen_address: 127.0.0.1:6000
  worker_threads: 3
  max_points_per_scan: 5000
  max_region_cells: 123456
)");
  Result<ServerConfig> c = ServerConfigFromYaml(doc);
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->map.resolution, 0.2);
  EXPECT_EQ(c->map.tile_size, 32);
  EXPECT_EQ(c->listen_address, "127.0.0.1:6000");
  EXPECT_EQ(c->worker_threads, 3);
  EXPECT_EQ(c->limits.max_points_per_scan, 5000u);
  EXPECT_EQ(c->limits.max_region_cells, 123456u);
}

TEST(ServerConfigTest, EmptyServerSectionMeansDefaults) {
  Result<ServerConfig> c = ServerConfigFromYaml(YAML::Load("server:\nresolution: 0.2\n"));
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->listen_address, ServerConfig{}.listen_address);
  EXPECT_EQ(c->map.resolution, 0.2);
}

TEST(ServerConfigTest, ErrorsNameTheKey) {
  auto error = [](const char* text) {
    Result<ServerConfig> c = ServerConfigFromYaml(YAML::Load(text));
    return c.ok() ? std::string("ok") : c.status().message();
  };
  EXPECT_NE(error("server: {bogus: 1}").find("server.bogus"), std::string::npos);
  EXPECT_NE(error("server: {max_robots: -3}").find("server.max_robots"), std::string::npos);
  EXPECT_NE(error("server: {max_coordinate: abc}").find("server.max_coordinate"),
            std::string::npos);
  EXPECT_NE(error("server: {log_level: loud}").find("server.log_level"), std::string::npos);
  EXPECT_NE(error("resolution: -1").find("resolution"), std::string::npos);
  EXPECT_NE(error("server: {max_points_per_scan: 100000000}").find("max_message_bytes"),
            std::string::npos);
}

TEST(ServerConfigTest, OverridesApplyToEitherSection) {
  ServerConfig c;
  ASSERT_TRUE(ApplyConfigOverride(c, "server.max_watchers=7").ok());
  ASSERT_TRUE(ApplyConfigOverride(c, "kernel_length=0.5").ok());
  EXPECT_EQ(c.limits.max_watchers, 7u);
  EXPECT_EQ(c.map.kernel_length, 0.5);
  EXPECT_FALSE(ApplyConfigOverride(c, "server.max_watchers").ok());
  EXPECT_FALSE(ApplyConfigOverride(c, "nonsense=1").ok());
  EXPECT_EQ(c.limits.max_watchers, 7u);  // a failed override changes nothing
}

TEST(ServerConfigTest, PrintedConfigReadsBackIdentically) {
  ServerConfig c;
  c.map.resolution = 0.25;
  c.limits.max_query_points = 42;
  c.listen_address = "127.0.0.1:7";
  const std::string text = ServerConfigToYaml(c);
  ASSERT_GT(ServerConfigKeys().size(), 10u);  // the loop below checks every key, so there are some
  for (const std::string& key : ServerConfigKeys()) {
    // "tls.cert_file" is written nested: tls: {cert_file: ...}
    EXPECT_NE(text.find(key.substr(key.rfind('.') + 1) + ":"), std::string::npos) << key;
  }
  Result<ServerConfig> back = ServerConfigFromYaml(YAML::Load(text));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(ServerConfigToYaml(*back), text);
  EXPECT_EQ(back->limits.max_query_points, 42u);
  EXPECT_EQ(back->map.resolution, 0.25);
}

}  // namespace
TEST(ServerConfigTest, StorageSection) {
  Result<ServerConfig> c = ServerConfigFromYaml(
      YAML::Load("storage: {data_dir: /tmp/m, durability: periodic, periodic_sync_ms: 50, "
                 "checkpoint_interval_s: 5}\n"));
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->storage.data_dir, "/tmp/m");
  EXPECT_EQ(c->storage.durability, "periodic");
  EXPECT_EQ(c->storage.periodic_sync_ms, 50u);
  EXPECT_EQ(c->storage.checkpoint_interval_s, 5.0);
  auto error = [](const char* text) {
    Result<ServerConfig> r = ServerConfigFromYaml(YAML::Load(text));
    return r.ok() ? std::string("ok") : r.status().message();
  };
  EXPECT_EQ(error("storage: {durability: maybe}").rfind("storage.durability", 0), 0u);
  EXPECT_EQ(error("storage: {periodic_sync_ms: -1}").rfind("storage.periodic_sync_ms", 0), 0u);
  EXPECT_EQ(error("storage: {checkpoint_interval_s: 0}").rfind("storage.checkpoint_interval_s", 0),
            0u);
  EXPECT_EQ(error("storage: {bogus: 1}").rfind("storage.bogus", 0), 0u);
  EXPECT_EQ(error("storage: {verify_on_start: maybe}").rfind("storage.verify_on_start", 0), 0u);
  EXPECT_EQ(error("storage: {max_memory_mb: 64}").rfind("storage.max_memory_mb", 0), 0u)
      << "a bound without a data_dir";
  EXPECT_EQ(error("storage: {data_dir: /x, max_memory_mb: -5}").rfind("storage.max_memory_mb", 0),
            0u);
  EXPECT_EQ(error("storage: {min_free_space_mb: -1}").rfind("storage.min_free_space_mb", 0), 0u);
  EXPECT_EQ(error("storage: {min_free_space_mb: 2000000000}").rfind("storage.min_free_space_mb", 0),
            0u);
  EXPECT_EQ(ServerConfig{}.storage.min_free_space_mb, 64u);
  EXPECT_EQ(ServerConfig{}.storage.dense_tiles_mb, 16u);
  EXPECT_EQ(error("storage: {dense_tiles_mb: -1}").rfind("storage.dense_tiles_mb", 0), 0u);
  EXPECT_EQ(error("storage: {dense_tiles_mb: 2000000000}").rfind("storage.dense_tiles_mb", 0), 0u);
  Result<ServerConfig> unpacked = ServerConfigFromYaml(YAML::Load("storage: {dense_tiles_mb: 0}"));
  ASSERT_TRUE(unpacked.ok()) << unpacked.status().ToString();  // a map in memory may pack
  EXPECT_EQ(unpacked->storage.dense_tiles_mb, 0u);
  EXPECT_EQ(error("server: {worker_nice: 20}").rfind("server.worker_nice", 0), 0u);
  EXPECT_EQ(ServerConfig{}.malloc_arenas, 2);
  EXPECT_EQ(error("server: {malloc_arenas: -1}").rfind("server.malloc_arenas", 0), 0u);
  EXPECT_EQ(ServerConfig{}.scan_bands, 1);
  EXPECT_EQ(error("server: {scan_bands: -1}").rfind("server.scan_bands", 0), 0u);
  EXPECT_EQ(error("server: {scan_bands: 65}").rfind("server.scan_bands", 0), 0u);
  EXPECT_TRUE(ServerConfig{}.worker_cpus.empty());  // not pinned
  EXPECT_EQ(error("server: {worker_cpus: [0, -1]}").rfind("server.worker_cpus", 0), 0u);
  EXPECT_EQ(error("server: {worker_cpus: [1024]}").rfind("server.worker_cpus", 0), 0u);
  EXPECT_EQ(error("server: {worker_cpus: [0.5]}").rfind("server.worker_cpus", 0), 0u);
  EXPECT_EQ(error("server: {worker_cpus: all}").rfind("server.worker_cpus", 0), 0u);
  Result<ServerConfig> pinned = ServerConfigFromYaml(YAML::Load("server: {worker_cpus: [1, 0]}"));
  ASSERT_TRUE(pinned.ok()) << pinned.status().ToString();
  EXPECT_EQ(pinned->worker_cpus, (std::vector<int>{1, 0}));
  ServerConfig pin_override;
  ASSERT_TRUE(ApplyConfigOverride(pin_override, "server.worker_cpus=[3]").ok());
  EXPECT_EQ(pin_override.worker_cpus, (std::vector<int>{3}));
  Result<ServerConfig> bounded = ServerConfigFromYaml(
      YAML::Load("server: {worker_nice: 0, malloc_arenas: 0, scan_bands: 0}\n"
                 "storage: {data_dir: /x, max_memory_mb: 512, verify_on_start: false}\n"));
  ASSERT_TRUE(bounded.ok()) << bounded.status().ToString();
  EXPECT_EQ(bounded->storage.max_memory_mb, 512u);
  EXPECT_FALSE(bounded->storage.verify_on_start);
  EXPECT_EQ(bounded->worker_nice, 0);
  EXPECT_EQ(bounded->malloc_arenas, 0);
  EXPECT_EQ(bounded->scan_bands, 0);
  ServerConfig o;
  ASSERT_TRUE(ApplyConfigOverride(o, "storage.data_dir=/x").ok());
  EXPECT_EQ(o.storage.data_dir, "/x");
  const std::string text = ServerConfigToYaml(*c);
  Result<ServerConfig> back = ServerConfigFromYaml(YAML::Load(text));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->storage.durability, "periodic");
  EXPECT_EQ(back->storage.data_dir, "/tmp/m");
}

// The limits and timeouts of the hostile-client fixes (issue 12): read, checked, named.
TEST(ServerConfigTest, TimeoutsAndCostLimits) {
  Result<ServerConfig> c = ServerConfigFromYaml(YAML::Load(
      "server: {ingest_idle_timeout_s: 2.5, stalled_write_timeout_s: 0, import_idle_timeout_s: 9, "
      "max_query_seconds: 1, max_sequence_jump: 1000, max_path_check_cells: 77}\n"));
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->limits.ingest_idle_timeout_s, 2.5);
  EXPECT_EQ(c->limits.stalled_write_timeout_s, 0.0);
  EXPECT_EQ(c->limits.import_idle_timeout_s, 9.0);
  EXPECT_EQ(c->limits.max_query_seconds, 1.0);
  EXPECT_EQ(c->limits.max_sequence_jump, 1000u);
  EXPECT_EQ(c->limits.max_path_check_cells, 77u);
  auto error = [](const char* text) {
    Result<ServerConfig> r = ServerConfigFromYaml(YAML::Load(text));
    return r.ok() ? std::string("ok") : r.status().message();
  };
  EXPECT_EQ(
      error("server: {stalled_write_timeout_s: -1}").rfind("server.stalled_write_timeout_s", 0),
      0u);
  EXPECT_EQ(error("server: {max_query_seconds: .nan}").rfind("server.max_query_seconds", 0), 0u);
  EXPECT_EQ(error("server: {max_path_check_cells: 0}").rfind("server.max_path_check_cells", 0), 0u);
}

}  // namespace bgkmap

namespace bgkmap {
namespace {

TEST(ServerConfigTest, GeoreferenceSection) {
  Result<ServerConfig> c = ServerConfigFromYaml(
      YAML::Load("georeference: {crs: 'EPSG:32610', origin: [551000.5, 4180000.25, 12.5]}\n"));
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->georeference.crs, "EPSG:32610");
  EXPECT_EQ(c->georeference.origin, (std::array<double, 3>{551000.5, 4180000.25, 12.5}));
  auto error = [](const char* text) {
    Result<ServerConfig> r = ServerConfigFromYaml(YAML::Load(text));
    return r.ok() ? std::string("ok") : r.status().message();
  };
  EXPECT_EQ(error("georeference: {origin: [1, 2, 3]}").rfind("georeference.origin: needs", 0), 0u);
  EXPECT_EQ(error("georeference: {crs: 'EPSG:4326', origin: [1, 2]}")
                .rfind("georeference.origin: expected", 0),
            0u);
  EXPECT_EQ(error("georeference: {crs: 'EPSG:4326', origin: [1, .nan, 3]}")
                .rfind("georeference.origin", 0),
            0u);
  EXPECT_EQ(error("georeference: {zone: 10}").rfind("georeference.zone: unknown key", 0), 0u);
  // --set and --print-config round trip.
  ServerConfig o;
  ASSERT_TRUE(ApplyConfigOverride(o, "georeference.crs=EPSG:2949").ok());
  ASSERT_TRUE(ApplyConfigOverride(o, "georeference.origin=[300000, 5270000, 0]").ok());
  Result<ServerConfig> back = ServerConfigFromYaml(YAML::Load(ServerConfigToYaml(o)));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->georeference.crs, "EPSG:2949");
  EXPECT_EQ(back->georeference.origin, (std::array<double, 3>{300000, 5270000, 0}));
  // No section: a local frame.
  EXPECT_TRUE(ServerConfigFromYaml(YAML::Load("server: {}\n"))->georeference.crs.empty());
}

TEST(ServerConfigTest, SecurityKeysReadNestedOrDottedAndAreCheckedTogether) {
  Result<ServerConfig> c = ServerConfigFromYaml(YAML::Load(
      "server: {tls: {cert_file: c.pem, key_file: k.pem}, auth: {tokens_file: t.yaml}}"));
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->tls.cert_file, "c.pem");
  EXPECT_EQ(c->tls.key_file, "k.pem");
  EXPECT_EQ(c->auth.tokens_file, "t.yaml");
  ServerConfig o;
  ASSERT_TRUE(ApplyConfigOverride(o, "server.tls.client_ca_file=ca.pem").ok());
  EXPECT_EQ(o.tls.client_ca_file, "ca.pem");
  EXPECT_EQ(ValidateSecurity(o).message(),
            "server.tls.client_ca_file: needs server.tls.cert_file (client certificates need TLS)");
  const Status unknown = ServerConfigFromYaml(YAML::Load("server: {tls: {cert: x}}")).status();
  EXPECT_EQ(unknown.message(), "server.tls.cert: unknown key");
  // Loopback needs nothing; anything else needs TLS and tokens, or insecure.
  ServerConfig exposed;
  exposed.listen_address = "0.0.0.0:50051";
  EXPECT_NE(ValidateSecurity(exposed).message().find("server.listen_address: '0.0.0.0:50051' is "
                                                     "not a loopback address"),
            std::string::npos);
  exposed.insecure = true;
  EXPECT_TRUE(ValidateSecurity(exposed).ok());
  for (const char* loopback : {"127.0.0.1:1", "localhost:1", "[::1]:1", "127.8.9.10:0"}) {
    EXPECT_TRUE(IsLoopbackAddress(loopback)) << loopback;
  }
  for (const char* other : {"0.0.0.0:1", "[::]:1", "10.0.0.1:1", "map.example:1", "garbage"}) {
    EXPECT_FALSE(IsLoopbackAddress(other)) << other;
  }
}

// A shard needs the cluster key or says it runs open: one line naming both settings.
TEST(ServerConfigTest, AShardNeedsAClusterKeyOrInsecure) {
  Result<ServerConfig> c =
      ServerConfigFromYaml(YAML::Load("cluster: {nats: \"nats://127.0.0.1:4222\", node: a}"));
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(ValidateCluster(*c).message(),
            "cluster.key_file: a shard needs cluster.key_file (a secret shared by the shards, at "
            "least 32 bytes) or cluster.insecure: true (then anyone who can publish to NATS can "
            "change the map)");
  ServerConfig open = *c;
  ASSERT_TRUE(ApplyConfigOverride(open, "cluster.insecure=true").ok());
  EXPECT_TRUE(ValidateCluster(open).ok());
  ServerConfig keyed = *c;
  ASSERT_TRUE(ApplyConfigOverride(keyed, "cluster.key_file=/etc/bgkmap/cluster.key").ok());
  EXPECT_TRUE(ValidateCluster(keyed).ok());
  // The path is configuration and printed; the secret is in the file, never read here.
  EXPECT_NE(ServerConfigToYaml(keyed).find("key_file: /etc/bgkmap/cluster.key"), std::string::npos);
  // A password or token in a NATS URL is not printed; the TLS and credentials files are.
  ASSERT_TRUE(ApplyConfigOverride(keyed,
                                  "cluster.nats=nats://bob:s3cret@10.0.0.1:4222,"
                                  "nats://t0ken@10.0.0.2:4222,nats://10.0.0.3:4222")
                  .ok());
  ASSERT_TRUE(ApplyConfigOverride(keyed, "cluster.nats_tls.ca_file=/etc/bgkmap/nats-ca.pem").ok());
  ASSERT_TRUE(ApplyConfigOverride(keyed, "cluster.nats_credentials=/etc/bgkmap/shard.creds").ok());
  const std::string printed = ServerConfigToYaml(keyed);
  EXPECT_EQ(printed.find("s3cret"), std::string::npos) << printed;
  EXPECT_EQ(printed.find("t0ken"), std::string::npos) << printed;
  EXPECT_NE(printed.find("nats://bob:***@10.0.0.1:4222,nats://***@10.0.0.2:4222,"
                         "nats://10.0.0.3:4222"),
            std::string::npos)
      << printed;
  EXPECT_NE(printed.find("ca_file: /etc/bgkmap/nats-ca.pem"), std::string::npos) << printed;
  EXPECT_NE(printed.find("nats_credentials: /etc/bgkmap/shard.creds"), std::string::npos);
  ServerConfig half = keyed;
  ASSERT_TRUE(ApplyConfigOverride(half, "cluster.nats_tls.cert_file=c.pem").ok());
  EXPECT_EQ(ValidateCluster(half).message(),
            "cluster.nats_tls.key_file: nats_tls.cert_file and nats_tls.key_file are set together");
  ASSERT_TRUE(ApplyConfigOverride(keyed, "cluster.dedupe_window_s=30").ok());
  EXPECT_NE(ValidateCluster(keyed).message().find("cluster.dedupe_window_s: must be at least 90"),
            std::string::npos);
}

// Streams per region: a bounded size, and not with a trimmed log (their copies are not trimmed).
TEST(ServerConfigTest, RegionPartitionsAreBoundedAndNotTrimmedYet) {
  Result<ServerConfig> c = ServerConfigFromYaml(
      YAML::Load("cluster: {nats: \"nats://127.0.0.1:4222\", node: a, insecure: true, "
                 "region_partitions: 8}"));
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->cluster.region_partitions, 8u);
  EXPECT_TRUE(ValidateCluster(*c).ok());
  ServerConfig huge = *c;
  ASSERT_TRUE(ApplyConfigOverride(huge, "cluster.region_partitions=5000").ok());
  EXPECT_EQ(ValidateCluster(huge).message(),
            "cluster.region_partitions: must be in [0, 4096] partitions");
  ServerConfig trimmed = *c;
  ASSERT_TRUE(ApplyConfigOverride(trimmed, "cluster.trim_lag_entries=1000").ok());
  EXPECT_EQ(ValidateCluster(trimmed).message(),
            "cluster.region_partitions: streams per region are not trimmed yet: set "
            "cluster.trim_lag_entries to 0 with cluster.region_partitions > 0");
}

}  // namespace
}  // namespace bgkmap
