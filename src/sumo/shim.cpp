// C shim over libsumo (or libtraci when compiled with -DLIBTRACI -DMPG_PREFIX=mpg_traci_).
// No C++ exception crosses this boundary: every body runs inside `guarded`, which turns
// libsumo::TraCIException, std::exception and anything else into -1 and a thread-local message.
#ifdef LIBTRACI
#include <libsumo/libtraci.h>
namespace api = libtraci;
#else
#include <libsumo/libsumo.h>
namespace api = libsumo;
#endif

#include <iostream>
#include <string>
#include <vector>

#include "shim.h"

namespace {

thread_local std::string g_error;
thread_local std::string g_strings;
thread_local std::vector<libsumo::TraCICollision> g_collisions;

template <typename F>
int guarded(F&& body) {
    try {
        body();
        g_error.clear();
        return 0;
    } catch (const libsumo::TraCIException& e) {
        g_error = e.what();
    } catch (const std::exception& e) {
        g_error = e.what();
        if (g_error.empty()) g_error = "unknown C++ exception";
    } catch (...) {
        g_error = "unknown non-standard exception";
    }
    return -1;
}

// libtraci reports its connection retries on std::cout; while it connects, they go to
// std::cerr instead, so that a caller's stdout (`cosim --json`) holds only its own output.
class CoutToCerr {
public:
    CoutToCerr() : saved_(std::cout.rdbuf(std::cerr.rdbuf())) {}
    ~CoutToCerr() { std::cout.rdbuf(saved_); }
    CoutToCerr(const CoutToCerr&) = delete;
    CoutToCerr& operator=(const CoutToCerr&) = delete;

private:
    std::streambuf* saved_;
};

void put_string(const std::string& s, const char** buf, size_t* len) {
    g_strings = s;
    *buf = g_strings.data();
    *len = g_strings.size();
}

void put_list(const std::vector<std::string>& items, const char** buf, size_t* len) {
    g_strings.clear();
    for (const auto& item : items) {
        g_strings += item;
        g_strings.push_back('\0');
    }
    *buf = g_strings.data();
    *len = g_strings.size();
}

}  // namespace

extern "C" {

const char* MPG_FN(last_error)(void) { return g_error.c_str(); }

int MPG_FN(start)(const char* const* argv, size_t argc) {
    return guarded([&] {
        std::vector<std::string> cmd(argv, argv + argc);
        CoutToCerr quiet;
        api::Simulation::start(cmd);
    });
}

int MPG_FN(attach)(int port, int order) {
    return guarded([&] {
#ifdef LIBTRACI
        CoutToCerr quiet;
        api::Simulation::init(port);
        api::Simulation::setOrder(order);
#else
        (void)port;
        (void)order;
        throw std::runtime_error("attaching to a running SUMO needs libtraci, not libsumo");
#endif
    });
}

int MPG_FN(step)(double until) { return guarded([&] { api::Simulation::step(until); }); }

int MPG_FN(close)(void) { return guarded([] { api::Simulation::close(); }); }

int MPG_FN(time)(double* out) { return guarded([&] { *out = api::Simulation::getTime(); }); }

int MPG_FN(delta_t)(double* out) { return guarded([&] { *out = api::Simulation::getDeltaT(); }); }

int MPG_FN(version)(const char** buf, size_t* len) {
    return guarded([&] { put_string(api::Simulation::getVersion().second, buf, len); });
}

int MPG_FN(min_expected)(int* out) {
    return guarded([&] { *out = api::Simulation::getMinExpectedNumber(); });
}

int MPG_FN(id_list)(int which, const char** buf, size_t* len) {
    return guarded([&] {
        switch (which) {
            case MPG_VEHICLES: put_list(api::Vehicle::getIDList(), buf, len); break;
            case MPG_LOADED: put_list(api::Simulation::getLoadedIDList(), buf, len); break;
            case MPG_DEPARTED: put_list(api::Simulation::getDepartedIDList(), buf, len); break;
            case MPG_ARRIVED: put_list(api::Simulation::getArrivedIDList(), buf, len); break;
            case MPG_TELEPORT_STARTING:
                put_list(api::Simulation::getStartingTeleportIDList(), buf, len);
                break;
            case MPG_EDGES: put_list(api::Edge::getIDList(), buf, len); break;
            case MPG_LANES: put_list(api::Lane::getIDList(), buf, len); break;
            default: throw std::invalid_argument("unknown id list " + std::to_string(which));
        }
    });
}

int MPG_FN(collisions)(size_t* count) {
    return guarded([&] {
        g_collisions = api::Simulation::getCollisions();
        *count = g_collisions.size();
    });
}

int MPG_FN(collision)(size_t index, MpgCollision* out) {
    return guarded([&] {
        const auto& c = g_collisions.at(index);
        *out = MpgCollision{c.collider.c_str(), c.victim.c_str(), c.type.c_str(), c.lane.c_str(),
                            c.pos, c.colliderSpeed, c.victimSpeed};
    });
}

int MPG_FN(lane_length)(const char* lane, double* out) {
    return guarded([&] { *out = api::Lane::getLength(lane); });
}

int MPG_FN(lane_vehicles)(const char* lane, const char** buf, size_t* len) {
    return guarded([&] { put_list(api::Lane::getLastStepVehicleIDs(lane), buf, len); });
}

int MPG_FN(vehicle_state)(const char* id, MpgVehicleState* out) {
    return guarded([&] {
        const std::string v(id);
        const auto pos = api::Vehicle::getPosition(v);
        out->x = pos.x;
        out->y = pos.y;
        out->angle = api::Vehicle::getAngle(v);
        out->speed = api::Vehicle::getSpeed(v);
        out->accel = api::Vehicle::getAcceleration(v);
        out->lane_pos = api::Vehicle::getLanePosition(v);
        out->length = api::Vehicle::getLength(v);
        out->width = api::Vehicle::getWidth(v);
        out->lane_index = api::Vehicle::getLaneIndex(v);
    });
}

int MPG_FN(vehicle_string)(const char* id, int which, const char** buf, size_t* len) {
    return guarded([&] {
        switch (which) {
            case MPG_LANE_ID: put_string(api::Vehicle::getLaneID(id), buf, len); break;
            case MPG_ROAD_ID: put_string(api::Vehicle::getRoadID(id), buf, len); break;
            case MPG_TYPE_ID: put_string(api::Vehicle::getTypeID(id), buf, len); break;
            case MPG_NEXT_SIGNAL: {
                const auto next = api::Vehicle::getNextTLS(id);
                put_string(next.empty() ? std::string()
                                        : std::string(1, next.front().state) + " " + std::to_string(next.front().dist),
                           buf, len);
                break;
            }
            default: throw std::invalid_argument("unknown vehicle string " + std::to_string(which));
        }
    });
}

int MPG_FN(vehicle_leader)(const char* id, double dist, const char** buf, size_t* len, double* gap) {
    return guarded([&] {
        const auto leader = api::Vehicle::getLeader(id, dist);
        put_string(leader.first, buf, len);
        *gap = leader.second;
    });
}

int MPG_FN(set_speed)(const char* id, double speed) {
    return guarded([&] { api::Vehicle::setSpeed(id, speed); });
}

int MPG_FN(set_speed_mode)(const char* id, int mode) {
    return guarded([&] { api::Vehicle::setSpeedMode(id, mode); });
}

int MPG_FN(set_color)(const char* id, int r, int g, int b) {
    return guarded([&] { api::Vehicle::setColor(id, libsumo::TraCIColor(r, g, b, 255)); });
}

int MPG_FN(set_lane_change_mode)(const char* id, int mode) {
    return guarded([&] { api::Vehicle::setLaneChangeMode(id, mode); });
}

int MPG_FN(change_lane)(const char* id, int lane_index, double duration) {
    return guarded([&] { api::Vehicle::changeLane(id, lane_index, duration); });
}

int MPG_FN(vehicle_add)(const char* id, const char* route, const char* type, const char* depart,
                        const char* lane, const char* pos, const char* speed) {
    return guarded([&] { api::Vehicle::add(id, route, type, depart, lane, pos, speed); });
}

int MPG_FN(move_to)(const char* id, const char* lane, double pos) {
    return guarded([&] { api::Vehicle::moveTo(id, lane, pos); });
}

int MPG_FN(route_add)(const char* id, const char* const* edges, size_t count) {
    return guarded([&] { api::Route::add(id, std::vector<std::string>(edges, edges + count)); });
}

}  // extern "C"
