// RocksDB merge operator keeping the maximum of 8-byte u64 values. Concurrent appenders record
// the map version and robot sequence numbers with Merge in their own write batch: whatever order
// the batches commit in, the stored value is the highest, without a read-modify-write.
#pragma once

#include <rocksdb/merge_operator.h>

namespace bgkmap::storage {

class MaxMergeOperator : public rocksdb::AssociativeMergeOperator {
 public:
  bool Merge(const rocksdb::Slice& key, const rocksdb::Slice* existing_value,
             const rocksdb::Slice& value, std::string* new_value,
             rocksdb::Logger* logger) const override;
  const char* Name() const override { return "bgkmap.MaxU64"; }
};

}  // namespace bgkmap::storage
