#pragma once
// Small RAII owners over the Cyclone DDS C API. This directory is the only code that
// includes dds.h. Every dds_* return is checked; failures throw DdsError with the call and
// dds_strretcode's text.

#include <dds/dds.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace mapmesh::transport {

class DdsError : public std::runtime_error {
 public:
  DdsError(const std::string& what, dds_return_t rc);
  dds_return_t code() const { return rc_; }

 private:
  dds_return_t rc_;
};

// Throws DdsError when rc is negative; returns rc otherwise.
dds_return_t Check(dds_return_t rc, const char* what);

inline dds_duration_t ToDuration(double seconds) { return static_cast<dds_duration_t>(seconds * 1e9); }

// Owns one DDS entity handle; deleting it deletes its children too.
class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t e) : e_(e) {}
  ~Entity() { Reset(); }
  Entity(Entity&& o) noexcept : e_(o.e_) { o.e_ = 0; }
  Entity& operator=(Entity&& o) noexcept {
    if (this != &o) {
      Reset();
      e_ = o.e_;
      o.e_ = 0;
    }
    return *this;
  }
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;

  dds_entity_t get() const { return e_; }
  explicit operator bool() const { return e_ > 0; }
  void Reset();

 protected:
  dds_entity_t e_ = 0;
};

// A QoS builder: Qos().Reliable().KeepAll().TransientLocal().
class Qos {
 public:
  Qos();
  ~Qos();
  Qos(const Qos& o);
  Qos& operator=(const Qos& o);

  Qos& Reliable(double max_blocking_s = 10.0);
  Qos& BestEffort();
  Qos& KeepAll();
  Qos& KeepLast(int depth);
  Qos& Volatile();
  Qos& TransientLocal();
  // Automatic liveliness with this lease: readers learn of a dead writer after about lease_s.
  Qos& Liveliness(double lease_s);
  // Writers only: do not dispose instances when the writer goes away.
  Qos& NoAutoDispose();
  // The one DDS partition of a writer, or the partition expression (wildcards allowed) of a
  // reader; readers match only writers whose partition matches.
  Qos& Partition(const std::string& name);
  // A reader's several partition expressions: it matches a writer in any of them.
  Qos& Partitions(const std::vector<std::string>& names);

  const dds_qos_t* get() const { return q_; }

 private:
  dds_qos_t* q_;
};

// A Cyclone domain with an explicit configuration (XML text or file:// URI). Create it
// before the participants of that domain; when absent, Cyclone reads CYCLONEDDS_URI.
class Domain : public Entity {
 public:
  Domain(dds_domainid_t id, const std::string& config);
};

class Participant : public Entity {
 public:
  explicit Participant(dds_domainid_t domain);
};

class Topic : public Entity {
 public:
  Topic(const Participant& p, const dds_topic_descriptor_t* desc, const std::string& name, const Qos& qos);
};

// Untyped writer and reader; the typed ones in typed.h wrap them.
class RawWriter : public Entity {
 public:
  RawWriter(const Participant& p, const Topic& t, const Qos& qos);
  void Write(const void* sample) const;
  // Gives up this writer's claim on the sample's instance (its key); the instance stays alive
  // while another writer holds it.
  void Unregister(const void* sample) const;
  // Number of readers currently matched.
  std::uint32_t MatchedReaders() const;
  // Number of readers ever matched (counts a reader again when it re-matches, e.g. after a
  // lapsed lease).
  std::uint32_t TotalMatchedReaders() const;
  // Waits until every reliable reader acknowledged; false on timeout.
  bool WaitForAcks(double timeout_s) const;
};

class RawReader : public Entity {
 public:
  RawReader(const Participant& p, const Topic& t, const Qos& qos);
};

// The partitions of the writers a reader is matched with, by publication handle (a taken
// sample's dds_sample_info_t::publication_handle). Every matched writer is looked up when the
// reader's matches change, so a writer that went away after its sample arrived is still known.
class WriterPartitions {
 public:
  explicit WriterPartitions(const RawReader& reader) : reader_(reader.get()) {}
  // The writer's partitions; nullptr when the writer was never seen matched.
  const std::vector<std::string>* Of(dds_instance_handle_t publication);
  // The writer's GUID (16 bytes): the same writer keeps it when it is matched anew (after a
  // lapsed lease, say), where its publication handle changes. nullptr as above.
  const std::string* GuidOf(dds_instance_handle_t publication);

 private:
  struct Writer {
    std::vector<std::string> partitions;
    std::string guid;
  };
  const Writer* Find(dds_instance_handle_t publication);
  void Refresh();
  bool Lookup(dds_instance_handle_t publication);
  dds_entity_t reader_;
  std::uint32_t seen_total_ = 0;
  std::map<dds_instance_handle_t, Writer> writers_;
};

// A guard condition: something a WaitSet can wait for, triggered from any thread.
class GuardCondition : public Entity {
 public:
  explicit GuardCondition(const Participant& p);
  void Trigger() const;
  bool Triggered() const;
};

// Waits until one of the attached readers has data, or a guard condition triggers.
class WaitSet : public Entity {
 public:
  explicit WaitSet(const Participant& p);
  // Attaches a reader (its data-available condition) or a guard condition. The attach
  // argument is returned by Wait when that entity triggers.
  void AttachReader(const RawReader& r, dds_attach_t tag);
  void AttachGuard(const GuardCondition& g, dds_attach_t tag);
  // Returns the tags of the entities that triggered; empty on timeout.
  std::vector<dds_attach_t> Wait(double timeout_s) const;

 private:
  std::vector<Entity> conditions_;
};

}  // namespace mapmesh::transport
