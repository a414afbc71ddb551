#include "cluster/log_change_feed.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "cluster/cluster_log.h"

namespace bgkmap::cluster {

LogChangeFeed::LogChangeFeed(const NatsClient& nats, const ClusterTrust& trust,
                             const PartitionLayout& layout, OnChange on_change)
    : nats_(nats), trust_(trust), layout_(layout), on_change_(std::move(on_change)) {
  // From the log's end as it is now: what a Watch started later must see comes after it.
  Result<uint64_t> end = LastSequence(nats_);
  if (end.ok()) last_ = *end;
  reader_ = std::thread([this] { Run(); });
}

LogChangeFeed::~LogChangeFeed() {
  stop_ = true;
  reader_.join();
}

void LogChangeFeed::Run() {
  // From the entry after the last one reported: no change is skipped or reported twice.
  FollowLogHeaders(
      nats_, last_ + 1, stop_, "cluster_change_feed_open_failed",
      [this](uint64_t sequence, natsMsg* msg) {
        last_ = sequence;
        // (Counted once, by the node's log reader, which reads the same entry.)
        if (!VerifyEntry(trust_, msg, /*headers_only=*/true).ok()) return;
        Result<LogEntryHeader> header = ReadEntryHeader(msg);
        if (!header.ok()) {
          spdlog::warn("event=cluster_change_feed_bad_entry sequence={} reason=\"{}\"", sequence,
                       header.status().message());
          return;
        }
        CellBox cells = header->changes;
        if (cells.empty()) {  // an entry older than the header: its partitions, halos included
          for (PartitionKey p : header->touched) {
            const CellBox h = layout_.HaloCells(p);
            cells.Extend(h.min);
            cells.Extend(h.max);
          }
        }
        if (!cells.empty()) on_change_(sequence, cells);
      });
}

}  // namespace bgkmap::cluster
