// rosbag2's SQLite storage (a `.db3` file): the `topics` table (id, name, type,
// serialization_format) and the `messages` table (topic_id, timestamp, data), read in timestamp
// order with SQLite itself (Debian's libsqlite3), the database opened read-only.
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/io/ros_recording.h"

namespace bgkmap::io {

// Every message of the file; DataLoss naming the file if it is not a rosbag2 database.
Result<std::vector<RecordedMessage>> ReadRosbag2Sqlite(const std::string& path);

}  // namespace bgkmap::io
