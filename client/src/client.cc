#include "bgkmap/client/client.h"

#include <fcntl.h>
#include <grpc/grpc.h>
#include <grpcpp/channel.h>
#include <grpcpp/client_context.h>
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "bgkmap/v1/map_service.grpc.pb.h"
#include "encode_pipeline.h"
#include "proto_codec.h"
#include "region_answer.h"
#include "scan_encoding.h"

namespace bgkmap {

using client_codec::AddDroppedHere;
using client_codec::EncodedScan;
using client_codec::EncodeHinted;
using client_codec::EncodePipeline;
using client_codec::EncodeScan;
using client_codec::FromGrpc;
using client_codec::FromProto;
using client_codec::ScanEncoding;
using client_codec::ToProto;

namespace {

// gRPC tears its library down when its last user goes away, which can block for seconds (an
// executor thread finishing a 10 s poll). A process-lifetime reference avoids that stall.
void KeepGrpcInitialized() {
  static std::once_flag once;
  std::call_once(once, [] { grpc_init(); });
}

void AddToken(grpc::ClientContext* context, const std::string& token) {
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
}

RpcStatus Malformed(const std::string& what) {
  return RpcStatus(RpcCode::kDataLoss, "malformed server response: " + what);
}

// A region answer, full or delta, from its stream of chunks.
RpcResult<RegionDelta> ReadRegionAnswer(v1::MapService::Stub& stub, grpc::ClientContext& context,
                                        const v1::RegionRequest& request) {
  std::unique_ptr<grpc::ClientReader<v1::RegionChunk>> reader = stub.QueryRegion(&context, request);
  RegionAnswerReader answer;
  v1::RegionChunk chunk;
  RpcStatus problem;
  while (reader->Read(&chunk)) {
    if (!problem.ok()) continue;  // drain the stream before Finish()
    if (Status s = answer.Add(chunk); !s.ok()) {
      problem = Malformed(s.message());
      context.TryCancel();
    }
  }
  grpc::Status status = reader->Finish();
  if (!problem.ok()) return problem;
  if (!status.ok()) return FromGrpc(status);
  Result<RegionDelta> done = std::move(answer).Finish();
  if (!done.ok()) return Malformed(done.status().message());
  return std::move(*done);
}

class GrpcIngestStream final : public IngestStream {
 public:
  // `threads` > 0: scans are encoded on that many threads, up to `ahead` scans ahead of the one
  // being written (client_codec::EncodePipeline); 0: each in Send().
  GrpcIngestStream(v1::MapService::Stub& stub, const std::string& token, ScanEncoding encoding,
                   int threads, int ahead)
      : encoding_(std::move(encoding)) {
    AddToken(&context_, token);
    stream_ = stub.Ingest(&context_);
    if (threads > 0) {
      pipeline_ = std::make_unique<EncodePipeline>(encoding_, threads, ahead,
                                                   [this](EncodedScan& s) { return Write(s); });
    }
  }
  ~GrpcIngestStream() override {
    if (!finished_) context_.TryCancel();  // a write blocked under flow control returns
    pipeline_.reset();
    if (!finished_) grpc::Status ignored = stream_->Finish();
  }

  bool Send(const ScanData& scan) override {
    if (pipeline_) return pipeline_->Submit(scan);
    EncodedScan encoded{scan.robot_id, scan.sequence, {}, {}};
    encoded.here = EncodeHinted(scan, sent_++, encoding_, &order_hint_, &encoded.message);
    return Write(encoded);
  }

  bool ReadAck(ScanAck* ack) override {
    v1::ScanAck message;
    if (!stream_->Read(&message)) return false;
    *ack = FromProto(message);
    std::lock_guard lock(dropped_mu_);
    auto here = dropped_here_.find({ack->robot_id, ack->sequence});
    if (here != dropped_here_.end()) {
      if (ack->status == AckStatus::kApplied) AddDroppedHere(here->second, &ack->counts);
      dropped_here_.erase(here);
    }
    return true;
  }

  void CloseSend() override {
    if (pipeline_) pipeline_->Close();  // every scan sent before WritesDone
    std::lock_guard lock(write_mu_);
    if (send_closed_) return;
    send_closed_ = true;
    stream_->WritesDone();
  }

  RpcStatus Finish(std::vector<ScanAck>* remaining) override {
    CloseSend();
    ScanAck ack;
    while (ReadAck(&ack)) {
      if (remaining != nullptr) remaining->push_back(std::move(ack));
    }
    finished_ = true;
    return FromGrpc(stream_->Finish());
  }

  void Cancel() override { context_.TryCancel(); }

 private:
  // Puts one encoded scan on the wire (the pipeline's writer thread, or Send()).
  bool Write(EncodedScan& scan) {
    {
      std::lock_guard lock(dropped_mu_);
      dropped_here_[{scan.robot_id, scan.sequence}] = scan.here;
    }
    std::lock_guard lock(write_mu_);
    if (send_closed_) return false;
    return stream_->Write(scan.message);
  }

  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::Scan, v1::ScanAck>> stream_;
  const ScanEncoding encoding_;
  std::mutex dropped_mu_;  // Send and ReadAck may run on two threads
  // What each unacked scan lost before sending, by (robot, sequence).
  std::map<std::pair<std::string, uint64_t>, ScanPointCounts> dropped_here_;
  std::mutex write_mu_;
  bool send_closed_ = false;
  bool finished_ = false;
  client_codec::OrderHint order_hint_;  // without the pipeline, which has its own
  std::atomic<uint64_t> sent_{0};
  std::unique_ptr<EncodePipeline> pipeline_;  // last: stopped before the rest goes
};

class GrpcWatch final : public WatchSubscription {
 public:
  GrpcWatch(v1::MapService::Stub& stub, const std::string& token, const WatchQuery& query,
            std::function<void(const TileUpdate&)> on_update)
      : on_update_(std::move(on_update)) {
    AddToken(&context_, token);
    v1::WatchRequest request;
    ToProto(query, &request);
    reader_ = stub.Watch(&context_, request);
    thread_ = std::thread([this] { Loop(); });
  }
  ~GrpcWatch() override {
    Cancel();
    Wait();
  }

  void Cancel() override { context_.TryCancel(); }

  RpcStatus Wait() override {
    std::lock_guard lock(join_mu_);
    if (thread_.joinable()) thread_.join();
    return status_;
  }

 private:
  void Loop() {
    v1::TileUpdate message;
    while (reader_->Read(&message)) on_update_(FromProto(message));
    status_ = FromGrpc(reader_->Finish());
  }

  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::TileUpdate>> reader_;
  std::function<void(const TileUpdate&)> on_update_;
  RpcStatus status_;
  std::mutex join_mu_;
  std::thread thread_;
};

}  // namespace

struct Client::Impl {
  ClientOptions options;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::MapService::Stub> stub;
  std::mutex encoding_mu;
  std::optional<ScanEncoding> encoding;  // asked for once

  // How scans go out: the options, and the map's filters from one Info call.
  ScanEncoding Encoding(Client& client) {
    std::lock_guard lock(encoding_mu);
    if (!encoding) {
      ScanEncoding e;
      e.step = options.compact_step;
      if (options.drop_filtered_points) {
        RpcResult<MapInfo> info = client.Info();
        if (info.ok()) e.filter = info->params;
        e.drop_height = options.drop_points_above_sensor;
      }
      encoding = e;
    }
    return *encoding;
  }

  // The deadline and the token of a unary or region call.
  void SetDeadline(grpc::ClientContext* context) const {
    AddToken(context, options.token);
    if (options.timeout.count() > 0) {
      context->set_deadline(std::chrono::system_clock::now() + options.timeout);
    }
  }
};

Client::Client(const std::string& target, ClientOptions options) : impl_(new Impl) {
  KeepGrpcInitialized();
  impl_->options = options;
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(options.max_message_bytes);
  args.SetMaxSendMessageSize(options.max_message_bytes);
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
  if (!options.tls_ca_pem.empty()) {
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = options.tls_ca_pem;
    ssl.pem_cert_chain = options.tls_cert_pem;
    ssl.pem_private_key = options.tls_key_pem;
    credentials = grpc::SslCredentials(ssl);
    if (!options.tls_server_name.empty()) {
      args.SetSslTargetNameOverride(options.tls_server_name);
    }
  }
  impl_->channel = grpc::CreateCustomChannel(target, credentials, args);
  impl_->stub = v1::MapService::NewStub(impl_->channel);
}

Client::~Client() = default;

bool Client::WaitForConnected(std::chrono::milliseconds timeout) {
  return impl_->channel->WaitForConnected(std::chrono::system_clock::now() + timeout);
}

RpcResult<ScanAck> Client::Insert(const ScanData& scan) {
  v1::Scan request;
  const ScanPointCounts here = EncodeScan(scan, impl_->Encoding(*this), &request);
  v1::ScanAck response;
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  grpc::Status status = impl_->stub->IngestScan(&context, request, &response);
  if (!status.ok()) return FromGrpc(status);
  ScanAck ack = FromProto(response);
  if (ack.status == AckStatus::kApplied) AddDroppedHere(here, &ack.counts);
  return ack;
}

std::unique_ptr<IngestStream> Client::OpenIngest() {
  return std::make_unique<GrpcIngestStream>(
      *impl_->stub, impl_->options.token, impl_->Encoding(*this),
      impl_->options.ingest_encode_threads, impl_->options.ingest_encode_ahead);
}

RpcResult<std::vector<ScanAck>> Client::IngestAll(
    std::span<const ScanData> scans, const std::function<void(const ScanAck&)>& on_ack) {
  std::unique_ptr<IngestStream> stream = OpenIngest();
  std::vector<ScanAck> acks;
  std::thread reader([&] {
    ScanAck ack;
    while (acks.size() < scans.size() && stream->ReadAck(&ack)) {
      if (on_ack) on_ack(ack);
      acks.push_back(std::move(ack));
    }
  });
  for (const ScanData& scan : scans) {
    if (!stream->Send(scan)) break;
  }
  stream->CloseSend();
  reader.join();
  RpcStatus status = stream->Finish(&acks);
  if (!status.ok()) return status;
  return acks;
}

RpcResult<Raster> Client::QueryRegion(const RegionQuery& query, uint64_t* map_version,
                                      uint64_t* history_id) {
  v1::RegionRequest request;
  ToProto(query, &request);
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  RpcResult<RegionDelta> answer = ReadRegionAnswer(*impl_->stub, context, request);
  if (!answer.ok()) return answer.status();
  if (!answer->full) return Malformed("a delta answered a query for the whole region");
  if (map_version != nullptr) *map_version = answer->map_version;
  if (history_id != nullptr) *history_id = answer->history_id;
  return std::move(answer->raster);
}

RpcResult<RegionDelta> Client::QueryRegionSince(const RegionQuery& query, uint64_t since_version,
                                                uint64_t since_history_id) {
  v1::RegionRequest request;
  ToProto(query, &request);
  request.set_since_version(since_version);
  request.set_since_history_id(since_history_id);
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  return ReadRegionAnswer(*impl_->stub, context, request);
}

RpcResult<PointValues> Client::QueryPoints(std::span<const std::array<double, 2>> points,
                                           const std::vector<Layer>& layers) {
  v1::PointsRequest request;
  ToProto(points, layers, &request);
  v1::PointsResponse response;
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  grpc::Status status = impl_->stub->QueryPoints(&context, request, &response);
  if (!status.ok()) return FromGrpc(status);
  PointValues out = FromProto(response);
  if (out.values.size() != points.size() * out.layers.size()) {
    return Malformed("point values do not match the request");
  }
  return out;
}

RpcResult<PathCheck> Client::CheckPath(const PathQuery& query) {
  v1::PathCheckRequest request;
  ToProto(query, &request);
  v1::PathCheckResponse response;
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  grpc::Status status = impl_->stub->CheckPath(&context, request, &response);
  if (!status.ok()) return FromGrpc(status);
  return FromProto(response);
}

std::unique_ptr<WatchSubscription> Client::Watch(const WatchQuery& query,
                                                 std::function<void(const TileUpdate&)> on_update) {
  return std::make_unique<GrpcWatch>(*impl_->stub, impl_->options.token, query,
                                     std::move(on_update));
}

RpcResult<MapInfo> Client::Info() {
  v1::InfoResponse response;
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  grpc::Status status = impl_->stub->Info(&context, v1::InfoRequest(), &response);
  if (!status.ok()) return FromGrpc(status);
  return FromProto(response);
}

RpcResult<ClearResult> Client::ClearRegion(const MetricBox& box) {
  v1::ClearRegionRequest request;
  ToProto(box, request.mutable_box());
  v1::ClearRegionResponse response;
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  grpc::Status status = impl_->stub->ClearRegion(&context, request, &response);
  if (!status.ok()) return FromGrpc(status);
  return FromProto(response);
}

RpcResult<RetiredRobot> Client::RetireRobot(const std::string& robot_id) {
  v1::RetireRobotRequest request;
  request.set_robot_id(robot_id);
  v1::RetireRobotResponse response;
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  grpc::Status status = impl_->stub->RetireRobot(&context, request, &response);
  if (!status.ok()) return FromGrpc(status);
  return RetiredRobot{response.last_sequence(), response.robots()};
}

namespace {

CorrectionResult FromProto(const v1::CorrectionSummary& s) {
  return {s.map_version(),        s.scans_revised(), s.records_replayed(),
          s.records_in_history(), s.tiles_changed(), s.seconds()};
}

}  // namespace

RpcResult<CorrectionResult> Client::CorrectPoses(
    const std::string& robot_id, const std::vector<std::pair<uint64_t, ScanPose>>& poses) {
  v1::CorrectPosesRequest request;
  request.set_robot_id(robot_id);
  for (const auto& [sequence, pose] : poses) {
    v1::PoseCorrection* c = request.add_corrections();
    c->set_sequence(sequence);
    ToProto(pose, c->mutable_pose());
  }
  v1::CorrectPosesResponse response;
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  grpc::Status status = impl_->stub->CorrectPoses(&context, request, &response);
  if (!status.ok()) return FromGrpc(status);
  return FromProto(response.summary());
}

RpcResult<CorrectionResult> Client::RemoveScans(const std::string& robot_id, uint64_t first,
                                                uint64_t last) {
  v1::RemoveScansRequest request;
  request.set_robot_id(robot_id);
  request.set_first_sequence(first);
  request.set_last_sequence(last);
  v1::RemoveScansResponse response;
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  grpc::Status status = impl_->stub->RemoveScans(&context, request, &response);
  if (!status.ok()) return FromGrpc(status);
  return FromProto(response.summary());
}

namespace {

constexpr size_t kArchiveChunkBytes = 1 << 20;

RpcStatus FileError(const std::string& what, const std::string& path) {
  return RpcStatus(RpcCode::kInvalidArgument, what + " " + path + ": " + std::strerror(errno));
}

// Flushes `path` to the disk, so a renamed archive survives a crash.
bool SyncFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}

}  // namespace

RpcResult<ExportResult> Client::ExportMap(const std::optional<MetricBox>& box,
                                          const std::string& path) {
  v1::ExportRequest request;
  if (box) ToProto(*box, request.mutable_box());
  const std::string partial = path + ".partial";
  std::ofstream out(partial, std::ios::binary | std::ios::trunc);
  if (!out) return FileError("cannot create", partial);
  // Removes the partial file unless the archive was completed and renamed.
  struct Cleanup {
    const std::string& file;
    bool keep = false;
    ~Cleanup() {
      if (!keep) std::remove(file.c_str());
    }
  } cleanup{partial};

  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  std::unique_ptr<grpc::ClientReader<v1::ArchiveChunk>> reader =
      impl_->stub->ExportMap(&context, request);
  ExportResult result;
  bool first = true, last = false;
  RpcStatus problem;
  v1::ArchiveChunk chunk;
  while (reader->Read(&chunk)) {
    if (!problem.ok()) continue;  // drain the stream before Finish()
    if (first) result.map_version = chunk.map_version();
    first = false;
    if (last) {
      problem = Malformed("archive chunk after the last one");
      context.TryCancel();
      continue;
    }
    out.write(chunk.data().data(), static_cast<std::streamsize>(chunk.data().size()));
    if (!out) {
      problem = FileError("writing", partial);
      context.TryCancel();
      continue;
    }
    result.bytes += chunk.data().size();
    if (chunk.last()) {
      last = true;
      result.tiles = chunk.tiles();
    }
  }
  grpc::Status status = reader->Finish();
  if (!problem.ok()) return problem;
  if (!status.ok()) return FromGrpc(status);
  if (!last) return Malformed("archive stream ended before its last chunk");
  out.close();
  if (!out || !SyncFile(partial)) return FileError("writing", partial);
  if (std::rename(partial.c_str(), path.c_str()) != 0) return FileError("cannot rename to", path);
  cleanup.keep = true;
  return result;
}

RpcResult<ImportResult> Client::ImportMap(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return FileError("cannot open", path);
  grpc::ClientContext context;
  impl_->SetDeadline(&context);
  v1::ImportResponse response;
  std::unique_ptr<grpc::ClientWriter<v1::ArchiveChunk>> writer =
      impl_->stub->ImportMap(&context, &response);
  v1::ArchiveChunk chunk;
  std::string buffer(kArchiveChunkBytes, '\0');
  RpcStatus problem;
  for (;;) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize n = in.gcount();
    if (n > 0) {
      chunk.set_data(buffer.data(), static_cast<size_t>(n));
      if (!writer->Write(chunk)) break;  // the server ended the call: Finish() says why
    }
    if (in.eof()) break;
    if (!in) {
      problem = FileError("reading", path);
      context.TryCancel();
      break;
    }
  }
  writer->WritesDone();
  grpc::Status status = writer->Finish();
  if (!problem.ok()) return problem;
  if (!status.ok()) return FromGrpc(status);
  return FromProto(response);
}

RpcResult<std::optional<uint64_t>> Client::LastSequence(const std::string& robot_id) {
  RpcResult<MapInfo> info = Info();
  if (!info.ok()) return info.status();
  const RobotInfo* robot = info->FindRobot(robot_id);
  if (robot == nullptr) return std::optional<uint64_t>();
  return std::optional<uint64_t>(robot->last_sequence);
}

}  // namespace bgkmap
