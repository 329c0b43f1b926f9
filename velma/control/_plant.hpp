// The MuJoCo side of ag_ex's 1 kHz cycle, compiled beside the law (included by
// _impedance.cpp after the Law class, only when MuJoCo's headers were found at build time).
//
// One ``Plant.cycle`` does what velma/executor/runtime.py ``Runtime.cycle`` does in Python:
// step the hands' and the head's servo setpoints and write them into ctrl
// (velma/control/hand.py ``Hands.step``, runtime.py ``Runtime._step_head``), gather Pinocchio's q, v
// from MuJoCo's qpos, qvel (velma/control/robot_model.py JointMap), compute the law
// (``Law::compute``), write the arm and torso torques into ctrl, and call mj_step. The
// contact scans (velma/control/hand.py ContactMonitor) and the robot state's numbers
// (velma/executor/state.py raw_state) read mjData here too. The Python code stays the
// reference (tests/velma/test_plant.py compares the two).
//
// MuJoCo is used through its headers only: the Python objects give the mjModel and mjData
// addresses (``_address``) and the caller gives mj_step's address (the libmujoco that the
// ``mujoco`` module loaded), so nothing is linked; the struct layout is that of the headers
// at build time, which is why velma/control/compiled.py uses a Plant only when
// ``MUJOCO_HEADER_VERSION`` equals the running ``mujoco.mj_version()``.

#include <mujoco/mujoco.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <utility>

namespace {

using MjStep = void (*)(const mjModel*, mjData*);

// Layout of one hand's row of setpoints (velma/control/hand.py, HAND_WIDTH and the offsets).
constexpr int hSpread = 0, hSpreadTarget = 1, hProximal = 2, hTarget = 5, hDistal = 8, hBroken = 11, hSteady = 14,
              kHandWidth = 15;

std::uintptr_t address_of(const py::object& obj) { return obj.attr("_address").cast<std::uintptr_t>(); }

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void check_index(const std::vector<int>& idx, std::int64_t bound, const char* what) {
  for (int i : idx)
    if (i < 0 || i >= bound) throw std::invalid_argument(std::string(what) + ": an index out of range");
}

class Plant {
 public:
  // model, data: mujoco.MjModel, mujoco.MjData (kept alive here). step: the address of
  // mj_step. qpos_adr, dof_adr: JointMap (nv each). arm_act: the arm motors (right 7, left 7);
  // torso_act: the torso motor. hand_side: per geom, the hand it belongs to (0 right, 1 left,
  // -1 none); part: per geom, -1 outside the robot, a hand's index, 2 elsewhere on the robot;
  // robot_body: per body, 1 on the robot. Raises ValueError on sizes or indices that do not fit.
  Plant(py::object model, py::object data, std::uintptr_t step, std::vector<int> qpos_adr, std::vector<int> dof_adr,
        std::vector<int> arm_act, int torso_act, std::vector<int> hand_side, std::vector<int> part,
        std::vector<int> robot_body)
      : model_obj_(std::move(model)),
        data_obj_(std::move(data)),
        m_(reinterpret_cast<const mjModel*>(address_of(model_obj_))),
        d_(reinterpret_cast<mjData*>(address_of(data_obj_))),
        step_(reinterpret_cast<MjStep>(step)),
        qpos_adr_(std::move(qpos_adr)),
        dof_adr_(std::move(dof_adr)),
        arm_act_(std::move(arm_act)),
        torso_act_(torso_act),
        hand_side_(std::move(hand_side)),
        part_(std::move(part)),
        robot_body_(std::move(robot_body)) {
    if (step_ == nullptr) throw std::invalid_argument("Plant: no mj_step");
    if (qpos_adr_.size() != dof_adr_.size()) throw std::invalid_argument("Plant: qpos_adr and dof_adr differ in size");
    check_index(qpos_adr_, m_->nq, "qpos_adr");
    check_index(dof_adr_, m_->nv, "dof_adr");
    if (arm_act_.size() != 14) throw std::invalid_argument("Plant: 14 arm motors");
    check_index(arm_act_, m_->nu, "arm_act");
    check_index({torso_act_}, m_->nu, "torso_act");
    if (static_cast<std::int64_t>(hand_side_.size()) != m_->ngeom ||
        static_cast<std::int64_t>(part_.size()) != m_->ngeom ||
        static_cast<std::int64_t>(robot_body_.size()) != m_->nbody)
      throw std::invalid_argument("Plant: hand_side and part per geom, robot_body per body");
  }

  // Bind the cycle's arrays once (kept alive here): the law and its arguments as Law.update's,
  // without q and v; q, v (nv,) receive the state the law used; parts (2,) the seconds spent
  // in gathering plus the law, and in mj_step. Raises ValueError on a size that does not fit.
  void bind(Law& law, Array cmd, Array torso, Array prev, Array limits, Array out, Array out_torso, Array q, Array v,
            Array parts) {
    const py::ssize_t nv = static_cast<py::ssize_t>(qpos_adr_.size());
    if (law.nv() != nv) throw std::invalid_argument("Plant.bind: the law has another nv");
    if (cmd.size() != 2 * kCmdWidth || torso.size() != 3 || prev.size() != 14 || limits.size() != 10 ||
        out.size() != 2 * oWidth || out_torso.size() != 2 || q.size() != nv || v.size() != nv || parts.size() != 2)
      throw std::invalid_argument("Plant.bind: an array has the wrong size");
    law_ = &law;
    arrays_ = {cmd, torso, prev, limits, out, out_torso, q, v, parts};
  }

  // Bind the servos' setpoints once (kept alive here): ``hands`` (2, 15) float64 as
  // velma/control/hand.py ``Hands.state``; per side (right, left) the spread motors (2 each),
  // the proximal and the distal servos (3 each), the proximal joints' qpos addresses (3 each)
  // and the proximal servos' gains kp (3 each, N·m/rad); ``head`` (4,) float64: the pan and
  // tilt setpoints, then their targets (rad); ``head_act`` the pan and tilt servos;
  // ``constants``: dt, BREAKAWAY_TORQUE, CLOSE_RATE, OPEN_RATE, SPREAD_RATE, DISTAL_RATIO,
  // DISTAL_MAX (hand.py) and the head's step HEAD_RATE·dt (runtime.py). Raises ValueError on
  // sizes or indices that do not fit.
  void bind_servos(Array hands, Array head, std::vector<int> spread_act, std::vector<int> prox_act,
                   std::vector<int> dist_act, std::vector<int> prox_q, std::vector<double> prox_kp,
                   std::vector<int> head_act, std::vector<double> constants) {
    if (hands.size() != 2 * kHandWidth || head.size() != 4 || spread_act.size() != 4 || prox_act.size() != 6 ||
        dist_act.size() != 6 || prox_q.size() != 6 || prox_kp.size() != 6 || head_act.size() != 2 ||
        constants.size() != 8)
      throw std::invalid_argument("Plant.bind_servos: an array has the wrong size");
    check_index(spread_act, m_->nu, "spread_act");
    check_index(prox_act, m_->nu, "prox_act");
    check_index(dist_act, m_->nu, "dist_act");
    check_index(head_act, m_->nu, "head_act");
    check_index(prox_q, m_->nq, "prox_q");
    hands_ = hands;
    head_ = head;
    spread_act_ = std::move(spread_act);
    prox_act_ = std::move(prox_act);
    dist_act_ = std::move(dist_act);
    prox_q_ = std::move(prox_q);
    prox_kp_ = std::move(prox_kp);
    head_act_ = std::move(head_act);
    servo_ = std::move(constants);
  }

  // One cycle (module comment) on the bound arrays. Raises RuntimeError before ``bind``,
  // else as Law.update.
  void cycle() {
    if (law_ == nullptr) throw std::runtime_error("Plant.cycle before Plant.bind");
    const auto t0 = std::chrono::steady_clock::now();
    if (!servo_.empty()) {
      step_hands();
      step_head();
    }
    double* q = arrays_[6].mutable_data();
    double* v = arrays_[7].mutable_data();
    for (std::size_t i = 0; i < qpos_adr_.size(); ++i) {
      q[i] = d_->qpos[qpos_adr_[i]];
      v[i] = d_->qvel[dof_adr_[i]];
    }
    double* o = arrays_[4].mutable_data();
    double* ot = arrays_[5].mutable_data();
    law_->compute(q, v, arrays_[0].data(), arrays_[1].data(), arrays_[2].data(), arrays_[3].data(), o, ot);
    for (int k = 0; k < 2; ++k)
      for (int i = 0; i < 7; ++i) d_->ctrl[arm_act_[7 * k + i]] = o[k * oWidth + oTau + i];
    d_->ctrl[torso_act_] = ot[0];
    double* p = arrays_[8].mutable_data();
    p[0] = seconds_since(t0);
    const auto t1 = std::chrono::steady_clock::now();
    {
      py::gil_scoped_release free;  // as the mujoco module's own mj_step
      step_(m_, d_);
    }
    p[1] = seconds_since(t1);
  }

  // ContactMonitor.touching: {body id: number of distinct geoms of hand ``side`` touching
  // it}, bodies off the robot only, in the order the Python scan meets them.
  py::dict touching(int side) const {
    py::dict result;
    for (const auto& [body, n] : touched(side)) result[py::int_(body)] = n;
    return result;
  }

  // ContactMonitor.self_contacts: (geom, geom) of each contact between two robot geoms that
  // are not both in one hand, in contact order.
  std::vector<std::pair<int, int>> self_contacts() const {
    std::vector<std::pair<int, int>> hits;
    for (int c = 0; c < d_->ncon; ++c) {
      const int a = d_->contact[c].geom[0], b = d_->contact[c].geom[1];
      if (a < 0 || b < 0) continue;
      const int pa = part_[a], pb = part_[b];
      if (pa >= 0 && pb >= 0 && (pa != pb || pa == 2)) hits.emplace_back(a, b);
    }
    return hits;
  }

  // ---- the world's side (velma/world/hardware.py SimulatedVelma) ------------------------
  // Bind the link's layout once: ``measured`` the offsets of MEASURED's time, q, v, ft, touch,
  // holding, hand, hand_seq, self_touch, head, disturb_seq (velma/world/layout.py), then
  // TOUCH_SLOTS, SELF_SLOTS and CONTACT_PERIOD; ``command`` the offsets of COMMAND's tau,
  // hand, head, disturb, then HAND_OP; ``tau_act`` the 15 motors of ``tau`` (right arm, left
  // arm, torso); ``ft_adr`` per side the force's and the torque's sensordata addresses;
  // ``seqs`` (3,) float64, bound: the last hand operation taken per side, then the last
  // disturbance. Needs ``bind_servos`` first (the hands' rows and the head are measured).
  // Raises ValueError on sizes or indices that do not fit (a negative offset among them).
  void bind_world(std::vector<int> measured, std::vector<int> command, std::vector<int> tau_act,
                  std::vector<int> ft_adr, Array seqs) {
    if (servo_.empty()) throw std::invalid_argument("Plant.bind_world: bind_servos first");
    if (measured.size() != 14 || command.size() != 5 || tau_act.size() != 15 || ft_adr.size() != 4 ||
        seqs.size() != 3)
      throw std::invalid_argument("Plant.bind_world: an argument has the wrong size");
    if (measured[11] < 0 || measured[12] < 0 || measured[13] < 4)
      throw std::invalid_argument("Plant.bind_world: slots must be >= 0 and the contact period >= 4");
    check_index(tau_act, m_->nu, "tau_act");
    check_index(ft_adr, m_->nsensordata - 2, "ft_adr");
    if (*std::min_element(measured.begin(), measured.begin() + 11) < 0 ||
        *std::min_element(command.begin(), command.begin() + 4) < 0 || command[4] < 1)
      throw std::invalid_argument("Plant.bind_world: a negative offset, or HAND_OP < 1");
    // how far measure and apply write and read: a shorter vector is refused there
    const int nv = static_cast<int>(qpos_adr_.size());
    measured_size_ = std::max({measured[0] + 1, measured[1] + nv, measured[2] + nv, measured[3] + 12,
                               measured[4] + 4 * measured[11], measured[5] + 1, measured[6] + 2 * kHandWidth,
                               measured[7] + 2, measured[8] + 2 * measured[12], measured[9] + 2, measured[10] + 1});
    command_size_ = std::max({command[0] + 15, command[1] + 2 * command[4], command[2] + 2, command[3] + 6});
    measured_ = std::move(measured);
    command_ = std::move(command);
    tau_act_ = std::move(tau_act);
    world_ft_ = std::move(ft_adr);
    seqs_ = seqs;
  }

  // SimulatedVelma.measure: this cycle's measured state into ``out`` (the link's MEASURED
  // vector; ``touch`` and ``self_touch`` rewritten on their phases of ``cycles``, so keep
  // ``out`` between calls). Raises RuntimeError before ``bind_world``, ValueError for an ``out``
  // shorter than the layout.
  void measure(Array& out, std::int64_t cycles, bool holding) const {
    if (measured_.empty()) throw std::runtime_error("Plant.measure before Plant.bind_world");
    if (out.size() < measured_size_) throw std::invalid_argument("Plant.measure: out is shorter than the layout");
    double* o = out.mutable_data();
    const int* at = measured_.data();
    o[at[0]] = d_->time;
    for (std::size_t i = 0; i < qpos_adr_.size(); ++i) {
      o[at[1] + i] = d_->qpos[qpos_adr_[i]];
      o[at[2] + i] = d_->qvel[dof_adr_[i]];
    }
    for (int k = 0; k < 2; ++k) {
      std::copy_n(d_->sensordata + world_ft_[2 * k], 3, o + at[3] + 6 * k);
      std::copy_n(d_->sensordata + world_ft_[2 * k + 1], 3, o + at[3] + 6 * k + 3);
    }
    const int touch_slots = at[11], self_slots = at[12], period = at[13];
    const std::int64_t phase = cycles % period;
    for (int k = 0; k < 2; ++k) {
      if (phase != k * period / 2) continue;  // each hand once a period, half a period apart
      auto seen = touched(k);  // the most touched first; the scan's order among equals
      std::stable_sort(seen.begin(), seen.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
      double* slots = o + at[4] + 2 * touch_slots * k;
      for (int i = 0; i < touch_slots; ++i) {
        const bool used = i < static_cast<int>(seen.size());
        slots[2 * i] = used ? seen[i].first : -1.0;
        slots[2 * i + 1] = used ? seen[i].second : 0.0;
      }
    }
    if (phase == period / 4) {  // between the two hands' scans
      const auto pairs = self_contacts();
      double* slots = o + at[8];
      for (int i = 0; i < self_slots; ++i) {
        const bool used = i < static_cast<int>(pairs.size());
        slots[2 * i] = used ? pairs[i].first : -1.0;
        slots[2 * i + 1] = used ? pairs[i].second : -1.0;
      }
    }
    o[at[5]] = holding ? 1.0 : 0.0;
    std::copy_n(hands_.data(), 2 * kHandWidth, o + at[6]);
    const double* seq = seqs_.data();
    o[at[7]] = seq[0];
    o[at[7] + 1] = seq[1];
    o[at[9]] = head_.data()[0];
    o[at[9] + 1] = head_.data()[1];
    o[at[10]] = seq[2];
  }

  // The everyday part of SimulatedVelma.apply: the torques into ctrl and the head's targets;
  // returns which of the rest the caller has to take (bit k: hand k's operation has a new
  // sequence number; bit 2: the disturbance has). Raises RuntimeError before ``bind_world``,
  // ValueError for a ``command`` shorter than the layout.
  int apply(const Array& command) {
    if (command_.empty()) throw std::runtime_error("Plant.apply before Plant.bind_world");
    if (command.size() < command_size_) throw std::invalid_argument("Plant.apply: command is shorter than the layout");
    const double* c = command.data();
    const int* at = command_.data();
    for (int i = 0; i < 15; ++i) d_->ctrl[tau_act_[i]] = c[at[0] + i];
    double* h = head_.mutable_data();
    h[2] = c[at[2]];
    h[3] = c[at[2] + 1];
    const double* seq = seqs_.data();
    int fresh = 0;
    for (int k = 0; k < 2; ++k)
      if (c[at[1] + at[4] * k] != seq[k]) fresh |= 1 << k;
    if (c[at[3]] != seq[2]) fresh |= 4;
    return fresh;
  }

  // SimulatedVelma.step: the hands' and the head's servos, then one mj_step (without the
  // GIL). Raises RuntimeError before ``bind_servos``.
  void step_world() {
    if (servo_.empty()) throw std::runtime_error("Plant.step_world before Plant.bind_servos");
    step_hands();
    const double* h = head_.data();
    if (h[0] != h[2] || h[1] != h[3]) step_head();  // at rest most of the time
    py::gil_scoped_release free;
    step_(m_, d_);
  }

  // Where the numbers of velma/executor/state.py raw_state come from, and their layout (its
  // ``raw_layout``: joints at 0, grip at offsets[0], links at offsets[1], setpoint at
  // offsets[2], wrench at offsets[3], size offsets[4]): qpos at ``joint_qpos``, the grip sites
  // (2), the link bodies, the force and torque sensordata addresses per side (4). Raises
  // ValueError on indices or a layout that do not fit.
  void set_state_layout(std::vector<int> joint_qpos, std::vector<int> sites, std::vector<int> links,
                        std::vector<int> ft_adr, std::vector<int> offsets) {
    if (offsets.size() != 5 || sites.size() != 2 || ft_adr.size() != 4)
      throw std::invalid_argument("Plant.set_state_layout: 2 sites, 4 sensor addresses, 5 offsets");
    check_index(joint_qpos, m_->nq, "joint_qpos");
    check_index(sites, m_->nsite, "sites");
    check_index(links, m_->nbody, "links");
    check_index(ft_adr, m_->nsensordata - 2, "ft_adr");
    if (static_cast<int>(joint_qpos.size()) != offsets[0] || offsets[1] - offsets[0] != 24 ||
        static_cast<int>(links.size()) * 7 != offsets[2] - offsets[1] || offsets[3] - offsets[2] != 26 ||
        offsets[4] - offsets[3] != 12)
      throw std::invalid_argument("Plant.set_state_layout: the layout does not fit the indices");
    joint_qpos_ = std::move(joint_qpos);
    sites_ = std::move(sites);
    links_ = std::move(links);
    ft_adr_ = std::move(ft_adr);
    offsets_ = std::move(offsets);
  }

  // The numbers of raw_state that MuJoCo's data holds, now, into ``out`` (size offsets[4]);
  // the setpoint block is left as it is (the commands are the controller's, in Python).
  // Raises ValueError before ``set_state_layout`` or for an ``out`` of another size.
  void gather(Array& out) const {
    if (offsets_.empty() || out.size() != offsets_[4])
      throw std::invalid_argument("Plant.gather: no layout yet, or out of another size");
    gather_into(out.mutable_data());
  }

  // Publish the robot state from here (velma/executor/state.py ``StateWriter``): ``block`` is
  // the whole shared buffer of a velma/executor/handoff.py ``LatestValue`` (uint8), whose
  // sequence number sits at byte 0 and whose value starts at ``header`` (its length, u32,
  // then the bytes). Raises ValueError before ``set_state_layout`` or ``bind``, or for a
  // block too small for the value.
  void bind_state_block(py::array_t<std::uint8_t, py::array::c_style> block, int header) {
    if (offsets_.empty() || law_ == nullptr)
      throw std::invalid_argument("Plant.bind_state_block: set_state_layout and bind first");
    const std::size_t n = 8 * static_cast<std::size_t>(2 + offsets_[4]);
    if (header < 8 || static_cast<std::size_t>(block.size()) < header + 4 + n)
      throw std::invalid_argument("Plant.bind_state_block: the block is too small");
    block_ = block;
    header_ = header;
    scratch_.assign(2 + offsets_[4], 0.0);
  }

  // Let go of the block of ``bind_state_block`` (before the block is closed).
  void release_state_block() {
    block_ = py::array_t<std::uint8_t, py::array::c_style>();
    scratch_.clear();
  }

  // Write the state value now (state.py ``state_values``: sim time, ``names_version``, then
  // raw_state's numbers with the setpoint block from the bound commands) under the block's
  // sequence lock, as ``LatestValue.write`` does. Raises RuntimeError before
  // ``bind_state_block``.
  void publish_state(double names_version) {
    if (scratch_.empty()) throw std::runtime_error("Plant.publish_state before Plant.bind_state_block");
    double* v = scratch_.data();
    v[0] = d_->time;
    v[1] = names_version;
    gather_into(v + 2);
    const double* cmd = arrays_[0].data();
    for (int k = 0; k < 2; ++k) {
      const double* row = cmd + kCmdWidth * k;
      double* sp = v + 2 + offsets_[2] + 13 * k;
      if (row[kMode] == kCart) {
        sp[0] = 1.0;
        std::copy_n(row + kPos, 3, sp + 1);
        std::copy_n(row + kRot, 9, sp + 4);
      } else {
        std::fill_n(sp, 13, 0.0);
      }
    }
    std::uint8_t* b = block_.mutable_data();
    auto* seq = reinterpret_cast<std::uint64_t*>(b);
    const std::uint64_t s = __atomic_load_n(seq, __ATOMIC_RELAXED);
    __atomic_store_n(seq, s + 1, __ATOMIC_RELAXED);
    std::atomic_thread_fence(std::memory_order_release);
    const std::uint32_t n = static_cast<std::uint32_t>(8 * scratch_.size());
    std::memcpy(b + header_, &n, 4);  // little-endian u32, as handoff.py's "<I" on x86-64
    std::memcpy(b + header_ + 4, v, n);
    __atomic_store_n(seq, s + 2, __ATOMIC_RELEASE);
  }

 private:
  // (body, number of distinct geoms of hand ``side`` touching it) per body off the robot, in
  // the order the Python scan (ContactMonitor.touching) meets them.
  std::vector<std::pair<int, int>> touched(int side) const {
    std::vector<std::pair<int, int>> seen;  // (body, hand geom), each once
    std::vector<std::pair<int, int>> order;  // (body, count)
    for (int col = 0; col < 2; ++col) {
      for (int c = 0; c < d_->ncon; ++c) {
        const int g = d_->contact[c].geom[col], other = d_->contact[c].geom[1 - col];
        if (g < 0 || other < 0 || hand_side_[g] != side) continue;
        const int b = m_->geom_bodyid[other];
        if (robot_body_[b]) continue;
        const std::pair<int, int> key(b, g);
        if (std::find(seen.begin(), seen.end(), key) != seen.end()) continue;
        seen.push_back(key);
        auto it = std::find_if(order.begin(), order.end(), [b](const auto& e) { return e.first == b; });
        if (it == order.end())
          order.emplace_back(b, 1);
        else
          ++it->second;
      }
    }
    return order;
  }

  void gather_into(double* o) const {
    for (std::size_t i = 0; i < joint_qpos_.size(); ++i) o[i] = d_->qpos[joint_qpos_[i]];
    for (int k = 0; k < 2; ++k) {
      double* g = o + offsets_[0] + 12 * k;
      std::copy_n(d_->site_xpos + 3 * sites_[k], 3, g);
      std::copy_n(d_->site_xmat + 9 * sites_[k], 9, g + 3);
      double* w = o + offsets_[3] + 6 * k;
      std::copy_n(d_->sensordata + ft_adr_[2 * k], 3, w);
      std::copy_n(d_->sensordata + ft_adr_[2 * k + 1], 3, w + 3);
    }
    for (std::size_t i = 0; i < links_.size(); ++i) {
      double* l = o + offsets_[1] + 7 * i;
      std::copy_n(d_->xpos + 3 * links_[i], 3, l);
      std::copy_n(d_->xquat + 4 * links_[i], 4, l + 3);
    }
  }

  // velma/control/hand.py Hands.step on the bound rows: the same operations in the same order
  // (so the same doubles), a steady hand skipped.
  void step_hands() {
    const double dt = servo_[0], breakaway = servo_[1], close = servo_[2], open = servo_[3], spread_rate = servo_[4],
                 ratio = servo_[5], distal_max = servo_[6];
    double* rows = hands_.mutable_data();
    for (int s = 0; s < 2; ++s) {
      double* r = rows + kHandWidth * s;
      if (r[hSteady] != 0.0) continue;
      double prox[3], target[3], distal[3], delta[3], goal[3];
      bool broken[3], closing[3], slip[3], any = false;
      for (int i = 0; i < 3; ++i) {
        prox[i] = r[hProximal + i];
        target[i] = r[hTarget + i];
        distal[i] = r[hDistal + i];
        broken[i] = r[hBroken + i] != 0.0;
        delta[i] = target[i] - prox[i];
        closing[i] = delta[i] > 0;
        slip[i] = closing[i] && !broken[i] && d_->actuator_force[prox_act_[3 * s + i]] >= breakaway;
        any = any || slip[i] || broken[i];
      }
      if (any) {  // the setpoint at which the proximal servo pushes with the breakaway torque
        for (int i = 0; i < 3; ++i) {
          const double press = d_->qpos[prox_q_[3 * s + i]] + breakaway / prox_kp_[3 * s + i];
          const double follow = std::min(std::max(prox[i], press), target[i]);  // ratchet: never back
          if (broken[i])
            prox[i] = follow;
          else if (slip[i])
            prox[i] = std::min(prox[i], press);
          broken[i] = broken[i] || slip[i];
        }
      }
      bool steady = true;
      for (int i = 0; i < 3; ++i) {
        double distal_rate;
        if (!broken[i]) {
          const double rate = (closing[i] ? close : open) * dt;
          prox[i] = prox[i] + std::min(std::max(delta[i], -rate), rate);
          goal[i] = prox[i] * ratio;
          distal_rate = open * dt;
        } else {
          goal[i] = distal_max;
          distal_rate = close * ratio * dt;
        }
        distal[i] = distal[i] + std::min(std::max(goal[i] - distal[i], -distal_rate), distal_rate);
        steady = steady && !broken[i] && prox[i] == target[i] && distal[i] == goal[i];
      }
      const double ds = r[hSpreadTarget] - r[hSpread];
      r[hSpread] += std::min(std::max(ds, -spread_rate * dt), spread_rate * dt);
      for (int i = 0; i < 3; ++i) {
        r[hProximal + i] = prox[i];
        r[hDistal + i] = distal[i];
        r[hBroken + i] = broken[i] ? 1.0 : 0.0;
        d_->ctrl[prox_act_[3 * s + i]] = prox[i];
        d_->ctrl[dist_act_[3 * s + i]] = distal[i];
      }
      d_->ctrl[spread_act_[2 * s]] = r[hSpread];
      d_->ctrl[spread_act_[2 * s + 1]] = r[hSpread];
      r[hSteady] = steady && r[hSpread] == r[hSpreadTarget] ? 1.0 : 0.0;
    }
  }

  // runtime.py Runtime._step_head: each setpoint one step (≤ HEAD_RATE·dt) towards its target.
  void step_head() {
    double* h = head_.mutable_data();
    const double rate = servo_[7];
    for (int i = 0; i < 2; ++i) {
      h[i] += std::min(std::max(h[2 + i] - h[i], -rate), rate);
      d_->ctrl[head_act_[i]] = h[i];
    }
  }

  py::object model_obj_, data_obj_;
  const mjModel* m_;
  mjData* d_;
  MjStep step_;
  std::vector<int> qpos_adr_, dof_adr_, arm_act_;
  int torso_act_;
  std::vector<int> hand_side_, part_, robot_body_;
  Law* law_ = nullptr;
  std::vector<Array> arrays_;  // cmd, torso, prev, limits, out, out_torso, q, v, parts
  std::vector<int> joint_qpos_, sites_, links_, ft_adr_, offsets_;
  Array hands_, head_;
  std::vector<int> spread_act_, prox_act_, dist_act_, prox_q_, head_act_;
  std::vector<double> prox_kp_, servo_;  // servo_: bind_servos' constants (empty: not bound)
  py::array_t<std::uint8_t, py::array::c_style> block_;
  int header_ = 0;
  std::vector<double> scratch_;  // the state value being written (empty: no block bound)
  std::vector<int> measured_, command_, tau_act_, world_ft_;  // bind_world's (empty: not bound)
  py::ssize_t measured_size_ = 0, command_size_ = 0;            // the shortest vectors they fit
  Array seqs_;
};

}  // namespace
