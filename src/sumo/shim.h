/* C interface over the libsumo / libtraci calls mpgdrive needs (see shim.cpp).
 *
 * The same source is compiled twice: against libsumo (SUMO in this process, prefix
 * mpg_sumo_) and against libtraci (a SUMO or sumo-gui process over TCP, prefix mpg_traci_).
 * MPG_PREFIX selects the prefix; bindgen reads this header once per prefix.
 *
 * Every function returns 0 on success and -1 on failure; then MPG_FN(last_error)() holds
 * SUMO's message (thread-local, valid until the next call on the same thread).
 * Strings returned through `const char** buf, size_t* len` point into a thread-local buffer
 * valid until the next call that returns strings; lists are '\0'-terminated items back to back.
 */
#ifndef MPG_SHIM_H
#define MPG_SHIM_H

#include <stddef.h>

#ifndef MPG_PREFIX
#define MPG_PREFIX mpg_sumo_
#endif
#define MPG_CAT2(a, b) a##b
#define MPG_CAT(a, b) MPG_CAT2(a, b)
#define MPG_FN(name) MPG_CAT(MPG_PREFIX, name)

#ifdef __cplusplus
extern "C" {
#endif

/** What SUMO reports about one vehicle in one call. */
typedef struct MpgVehicleState {
    double x;          /* position (m), front bumper centre, network coordinates */
    double y;
    double angle;      /* degrees, SUMO's convention (0 = north, clockwise) */
    double speed;      /* m/s */
    double accel;      /* m/s^2, last step */
    double lane_pos;   /* m from the start of the lane to the front bumper */
    double length;     /* m */
    double width;      /* m */
    int lane_index;    /* 0 = right-most */
} MpgVehicleState;

/** One collision reported by SUMO; the strings stay valid until the next collisions call. */
typedef struct MpgCollision {
    const char* collider;
    const char* victim;
    const char* kind;
    const char* lane;
    double pos;
    double collider_speed;
    double victim_speed;
} MpgCollision;

/** Which id list `id_list` returns. */
enum MpgIdList {
    MPG_VEHICLES = 0,
    MPG_LOADED = 1,
    MPG_DEPARTED = 2,
    MPG_ARRIVED = 3,
    MPG_TELEPORT_STARTING = 4,
    MPG_EDGES = 5,
    MPG_LANES = 6,
};

/** Which string `vehicle_string` returns. */
enum MpgVehicleString {
    MPG_LANE_ID = 0,
    MPG_ROAD_ID = 1,
    MPG_TYPE_ID = 2,
    /* The next traffic light on the vehicle's route: its state (one of SUMO's signal
       characters, r, y, G, ...), a space and the distance to it in metres ("r 35.200000"), or
       "" when none lies ahead. */
    MPG_NEXT_SIGNAL = 3,
};

const char* MPG_FN(last_error)(void);
/* argv[0] is the binary (sumo, sumo-gui); libsumo ignores it and runs in process. */
int MPG_FN(start)(const char* const* argv, size_t argc);
/* libtraci only: join a running SUMO on localhost:port as client number `order`. */
int MPG_FN(attach)(int port, int order);
int MPG_FN(step)(double until);
int MPG_FN(close)(void);
int MPG_FN(time)(double* out);
int MPG_FN(delta_t)(double* out);
int MPG_FN(min_expected)(int* out);
/* SUMO's version string ("SUMO 1.15.0"). */
int MPG_FN(version)(const char** buf, size_t* len);
int MPG_FN(id_list)(int which, const char** buf, size_t* len);
int MPG_FN(collisions)(size_t* count);
int MPG_FN(collision)(size_t index, MpgCollision* out);
int MPG_FN(lane_length)(const char* lane, double* out);
/* Vehicles on a lane after the last step, as an id list. */
int MPG_FN(lane_vehicles)(const char* lane, const char** buf, size_t* len);
int MPG_FN(vehicle_state)(const char* id, MpgVehicleState* out);
int MPG_FN(vehicle_string)(const char* id, int which, const char** buf, size_t* len);
int MPG_FN(vehicle_leader)(const char* id, double dist, const char** buf, size_t* len, double* gap);
int MPG_FN(set_speed)(const char* id, double speed);
int MPG_FN(set_speed_mode)(const char* id, int mode);
int MPG_FN(set_lane_change_mode)(const char* id, int mode);
/* Colours a vehicle (as drawn by sumo-gui), opaque, channels 0-255. */
int MPG_FN(set_color)(const char* id, int r, int g, int b);
int MPG_FN(change_lane)(const char* id, int lane_index, double duration);
int MPG_FN(vehicle_add)(const char* id, const char* route, const char* type, const char* depart,
                        const char* lane, const char* pos, const char* speed);
/* Moves a vehicle to `pos` on `lane`; inserts a loaded vehicle that has not departed yet. */
int MPG_FN(move_to)(const char* id, const char* lane, double pos);
int MPG_FN(route_add)(const char* id, const char* const* edges, size_t count);

#ifdef __cplusplus
}
#endif

#endif
