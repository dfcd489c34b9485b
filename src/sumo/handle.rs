//! The safe handle over the shim: one live simulation per process, typed errors carrying SUMO's
//! message, close on drop.

use crate::sumo::SumoError;
use crate::sumo::ffi::libsumo as c;
use crate::sumo::ffi::{self, Api, MpgCollision, MpgVehicleState};
use std::ffi::{CStr, CString, c_char, c_int};
use std::marker::PhantomData;
use std::sync::atomic::{AtomicBool, Ordering};

/// libsumo::INVALID_DOUBLE_VALUE: what SUMO reports for a vehicle not in the network.
const INVALID_DOUBLE: f64 = -1_073_741_824.0;

/// True while a [`Sumo`] handle exists (libsumo holds one simulation per process).
static LIVE: AtomicBool = AtomicBool::new(false);

/// Which library carries the calls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// SUMO inside this process (headless, fastest).
    Libsumo,
    /// A SUMO or sumo-gui process over TCP (libtraci).
    Traci,
}

/// What SUMO reports about one vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleState {
    /// Front-bumper position in network coordinates (m).
    pub x: f64,
    /// Front-bumper position in network coordinates (m).
    pub y: f64,
    /// Heading in SUMO's convention (degrees, 0 = north, clockwise).
    pub angle: f64,
    /// Speed (m/s).
    pub speed: f64,
    /// Acceleration over the last step (m/s^2).
    pub accel: f64,
    /// Distance of the front bumper from the start of its lane (m).
    pub lane_pos: f64,
    /// Vehicle length (m).
    pub length: f64,
    /// Vehicle width (m).
    pub width: f64,
    /// Lane index on its edge, 0 = right-most.
    pub lane_index: i32,
}

/// One collision as SUMO reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct Collision {
    /// The vehicle that hit.
    pub collider: String,
    /// The vehicle that was hit.
    pub victim: String,
    /// SUMO's collision type (collision, frontal, junction, ...).
    pub kind: String,
    /// Lane id.
    pub lane: String,
    /// Position along the lane (m).
    pub pos: f64,
}

/// The live simulation. Not `Send` or `Sync`: libsumo is not thread-safe, so the handle stays
/// on the thread that started it. Dropping it closes the simulation (or, when attached,
/// leaves it running and disconnects).
pub struct Sumo {
    api: &'static Api,
    closed: bool,
    _not_send: PhantomData<*const ()>,
}

/// Splits a shim list: items each terminated by NUL.
fn split_list(joined: &str) -> Vec<String> {
    joined.split_terminator('\0').map(str::to_owned).collect()
}

fn cstring(s: &str) -> Result<CString, SumoError> {
    CString::new(s).map_err(|_| SumoError::Nul(s.to_owned()))
}

impl Sumo {
    fn claim(api: &'static Api) -> Result<Sumo, SumoError> {
        LIVE.compare_exchange(false, true, Ordering::AcqRel, Ordering::Acquire)
            .map_err(|_| SumoError::AlreadyRunning)?;
        Ok(Sumo {
            api,
            closed: false,
            _not_send: PhantomData,
        })
    }

    /// Starts a simulation with a SUMO command line (`args[0]` is the binary: `sumo`, or
    /// `sumo-gui` with [`Backend::Traci`]).
    pub fn start(backend: Backend, args: &[String]) -> Result<Sumo, SumoError> {
        let mut sumo = Self::claim(match backend {
            Backend::Libsumo => &ffi::LIBSUMO,
            Backend::Traci => &ffi::LIBTRACI,
        })?;
        let owned = args.iter().map(|a| cstring(a)).collect::<Result<Vec<_>, _>>()?;
        let ptrs: Vec<*const c_char> = owned.iter().map(|c| c.as_ptr()).collect();
        // SAFETY: `ptrs` holds `ptrs.len()` valid NUL-terminated strings that outlive the call;
        // the shim copies them into a std::vector<std::string>.
        let rc = unsafe { (sumo.api.start)(ptrs.as_ptr(), ptrs.len()) };
        if let Err(e) = sumo.check("start", rc) {
            sumo.closed = true; // nothing to close
            return Err(e);
        }
        Ok(sumo)
    }

    /// Joins a SUMO already running on `localhost:port` with `--num-clients N`, as client
    /// number `order` (libtraci). The simulation steps when every client has asked to step.
    pub fn attach(port: u16, order: i32) -> Result<Sumo, SumoError> {
        let mut sumo = Self::claim(&ffi::LIBTRACI)?;
        // SAFETY: plain integer arguments; errors come back as a return code.
        let rc = unsafe { (sumo.api.attach)(c_int::from(port), order) };
        if let Err(e) = sumo.check("attach", rc) {
            sumo.closed = true;
            return Err(e);
        }
        Ok(sumo)
    }

    /// Which backend this handle uses ("libsumo" or "traci").
    pub fn backend_name(&self) -> &'static str {
        self.api.name
    }

    fn check(&self, call: &'static str, rc: c_int) -> Result<(), SumoError> {
        if rc == 0 {
            return Ok(());
        }
        // SAFETY: last_error returns a pointer to a thread-local NUL-terminated string that
        // stays valid until the next shim call on this thread; it is copied at once.
        let message = unsafe { CStr::from_ptr((self.api.last_error)()) }
            .to_string_lossy()
            .into_owned();
        Err(SumoError::Sumo { call, message })
    }

    /// Copies a string or list the shim left in its thread-local buffer.
    fn strings(
        &self,
        call: &'static str,
        rc: c_int,
        buf: *const c_char,
        len: usize,
    ) -> Result<String, SumoError> {
        self.check(call, rc)?;
        if len == 0 {
            return Ok(String::new());
        }
        // SAFETY: on success the shim set `buf` to `len` bytes of its thread-local buffer, which
        // stays valid until the next shim call on this thread; they are copied at once.
        let bytes = unsafe { std::slice::from_raw_parts(buf.cast::<u8>(), len) };
        Ok(String::from_utf8_lossy(bytes).into_owned())
    }

    fn id_list(&self, which: c::MpgIdList) -> Result<Vec<String>, SumoError> {
        let mut buf = std::ptr::null();
        let mut len = 0usize;
        // SAFETY: the out-pointers are valid for writes for the duration of the call.
        let rc = unsafe { (self.api.id_list)(which as c_int, &mut buf, &mut len) };
        Ok(split_list(&self.strings("id list", rc, buf, len)?))
    }

    /// Vehicles on a lane after the last step.
    pub fn lane_vehicles(&self, lane: &str) -> Result<Vec<String>, SumoError> {
        let id = cstring(lane)?;
        let mut buf = std::ptr::null();
        let mut len = 0usize;
        // SAFETY: `id` is a valid C string; the out-pointers are valid for writes.
        let rc = unsafe { (self.api.lane_vehicles)(id.as_ptr(), &mut buf, &mut len) };
        Ok(split_list(&self.strings("lane vehicles", rc, buf, len)?))
    }

    /// Advances one simulation step.
    pub fn step(&mut self) -> Result<(), SumoError> {
        // SAFETY: no pointers; errors come back as a return code.
        let rc = unsafe { (self.api.step)(0.0) };
        self.check("step", rc)
    }

    /// Simulation time (s).
    pub fn time(&self) -> Result<f64, SumoError> {
        let mut t = 0.0;
        // SAFETY: `t` is valid for a write.
        let rc = unsafe { (self.api.time)(&mut t) };
        self.check("time", rc).map(|()| t)
    }

    /// Step length (s).
    pub fn delta_t(&self) -> Result<f64, SumoError> {
        let mut t = 0.0;
        // SAFETY: `t` is valid for a write.
        let rc = unsafe { (self.api.delta_t)(&mut t) };
        self.check("delta_t", rc).map(|()| t)
    }

    /// Vehicles running or still waiting to be inserted.
    pub fn min_expected(&self) -> Result<i32, SumoError> {
        let mut n: c_int = 0;
        // SAFETY: `n` is valid for a write.
        let rc = unsafe { (self.api.min_expected)(&mut n) };
        self.check("min_expected", rc).map(|()| n)
    }

    /// Vehicles in the network now.
    pub fn vehicle_ids(&self) -> Result<Vec<String>, SumoError> {
        self.id_list(c::MpgIdList_MPG_VEHICLES)
    }

    /// Vehicles loaded (from route files or added) in the last step.
    pub fn loaded(&self) -> Result<Vec<String>, SumoError> {
        self.id_list(c::MpgIdList_MPG_LOADED)
    }

    /// Vehicles that departed in the last step.
    pub fn departed(&self) -> Result<Vec<String>, SumoError> {
        self.id_list(c::MpgIdList_MPG_DEPARTED)
    }

    /// Vehicles that arrived (left the network) in the last step.
    pub fn arrived(&self) -> Result<Vec<String>, SumoError> {
        self.id_list(c::MpgIdList_MPG_ARRIVED)
    }

    /// Vehicles that started a teleport in the last step.
    pub fn teleporting(&self) -> Result<Vec<String>, SumoError> {
        self.id_list(c::MpgIdList_MPG_TELEPORT_STARTING)
    }

    /// Edge ids of the network (internal edges included).
    pub fn edge_ids(&self) -> Result<Vec<String>, SumoError> {
        self.id_list(c::MpgIdList_MPG_EDGES)
    }

    /// Lane ids of the network (internal lanes included).
    pub fn lane_ids(&self) -> Result<Vec<String>, SumoError> {
        self.id_list(c::MpgIdList_MPG_LANES)
    }

    /// Length of a lane (m).
    pub fn lane_length(&self, lane: &str) -> Result<f64, SumoError> {
        let id = cstring(lane)?;
        let mut out = 0.0;
        // SAFETY: `id` is a valid C string and `out` is valid for a write.
        let rc = unsafe { (self.api.lane_length)(id.as_ptr(), &mut out) };
        self.check("lane length", rc).map(|()| out)
    }

    /// Collisions of the last step.
    pub fn collisions(&self) -> Result<Vec<Collision>, SumoError> {
        let mut count = 0usize;
        // SAFETY: `count` is valid for a write.
        let rc = unsafe { (self.api.collisions)(&mut count) };
        self.check("collisions", rc)?;
        let text = |p: *const c_char| {
            // SAFETY: the pointers point into the collision list the shim keeps until the next
            // collisions call; they are copied at once.
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        };
        (0..count)
            .map(|i| {
                let mut c = MpgCollision {
                    collider: std::ptr::null(),
                    victim: std::ptr::null(),
                    kind: std::ptr::null(),
                    lane: std::ptr::null(),
                    pos: 0.0,
                    collider_speed: 0.0,
                    victim_speed: 0.0,
                };
                // SAFETY: `c` is valid for a write; `i` is below the count the shim reported.
                let rc = unsafe { (self.api.collision)(i, &mut c) };
                self.check("collision", rc)?;
                Ok(Collision {
                    collider: text(c.collider),
                    victim: text(c.victim),
                    kind: text(c.kind),
                    lane: text(c.lane),
                    pos: c.pos,
                })
            })
            .collect()
    }

    /// State of one vehicle.
    pub fn vehicle(&self, id: &str) -> Result<VehicleState, SumoError> {
        let cid = cstring(id)?;
        let mut s = MpgVehicleState {
            x: 0.0,
            y: 0.0,
            angle: 0.0,
            speed: 0.0,
            accel: 0.0,
            lane_pos: 0.0,
            length: 0.0,
            width: 0.0,
            lane_index: 0,
        };
        // SAFETY: `cid` is a valid C string and `s` is valid for a write.
        let rc = unsafe { (self.api.vehicle_state)(cid.as_ptr(), &mut s) };
        self.check("vehicle state", rc)?;
        if s.x == INVALID_DOUBLE {
            return Err(SumoError::Sumo {
                call: "vehicle state",
                message: format!("vehicle '{id}' is loaded but not in the network (not inserted yet)"),
            });
        }
        Ok(VehicleState {
            x: s.x,
            y: s.y,
            angle: s.angle,
            speed: s.speed,
            accel: s.accel,
            lane_pos: s.lane_pos,
            length: s.length,
            width: s.width,
            lane_index: s.lane_index,
        })
    }

    fn vehicle_string(&self, id: &str, which: c::MpgVehicleString) -> Result<String, SumoError> {
        let cid = cstring(id)?;
        let mut buf = std::ptr::null();
        let mut len = 0usize;
        // SAFETY: `cid` is a valid C string; the out-pointers are valid for writes.
        let rc = unsafe { (self.api.vehicle_string)(cid.as_ptr(), which as c_int, &mut buf, &mut len) };
        self.strings("vehicle string", rc, buf, len)
    }

    /// Lane id of a vehicle.
    pub fn lane_id(&self, id: &str) -> Result<String, SumoError> {
        self.vehicle_string(id, c::MpgVehicleString_MPG_LANE_ID)
    }

    /// Edge id of a vehicle (an internal ":..." id on a junction).
    pub fn road_id(&self, id: &str) -> Result<String, SumoError> {
        self.vehicle_string(id, c::MpgVehicleString_MPG_ROAD_ID)
    }

    /// The next traffic light on a vehicle's route, if one lies ahead: its state (SUMO's
    /// signal character: `r` red, `y` yellow, `G`/`g` green, ...) and the distance from the
    /// vehicle's front to its stop line (m).
    pub fn next_signal(&self, id: &str) -> Result<Option<(char, f64)>, SumoError> {
        let s = self.vehicle_string(id, c::MpgVehicleString_MPG_NEXT_SIGNAL)?;
        Ok(s.split_once(' ')
            .and_then(|(state, dist)| Some((state.chars().next()?, dist.parse().ok()?))))
    }

    /// SUMO's version string, as SUMO reports it ("SUMO 1.15.0").
    pub fn version(&self) -> Result<String, SumoError> {
        let mut buf = std::ptr::null();
        let mut len = 0usize;
        // SAFETY: the out-pointers are valid for writes for the duration of the call.
        let rc = unsafe { (self.api.version)(&mut buf, &mut len) };
        self.strings("version", rc, buf, len)
    }

    /// Vehicle type id of a vehicle.
    pub fn type_id(&self, id: &str) -> Result<String, SumoError> {
        self.vehicle_string(id, c::MpgVehicleString_MPG_TYPE_ID)
    }

    /// The leader within `dist` metres on the vehicle's route and its gap, if any.
    pub fn leader(&self, id: &str, dist: f64) -> Result<Option<(String, f64)>, SumoError> {
        let cid = cstring(id)?;
        let mut buf = std::ptr::null();
        let mut len = 0usize;
        let mut gap = 0.0;
        // SAFETY: `cid` is a valid C string; the out-pointers are valid for writes.
        let rc = unsafe { (self.api.vehicle_leader)(cid.as_ptr(), dist, &mut buf, &mut len, &mut gap) };
        let leader = self.strings("leader", rc, buf, len)?;
        Ok((!leader.is_empty()).then_some((leader, gap)))
    }

    fn with_id(
        &mut self,
        call: &'static str,
        id: &str,
        f: impl FnOnce(*const c_char) -> c_int,
    ) -> Result<(), SumoError> {
        let cid = cstring(id)?;
        let rc = f(cid.as_ptr());
        self.check(call, rc)
    }

    /// Sets the speed the vehicle will have after the next step (m/s).
    pub fn set_speed(&mut self, id: &str, speed: f64) -> Result<(), SumoError> {
        let f = self.api.set_speed;
        self.with_id("setSpeed", id, |p| {
            // SAFETY: the pointer is a valid C string for the call.
            unsafe { f(p, speed) }
        })
    }

    /// Sets SUMO's speed mode bits (0: no checks at all, 31: all checks).
    pub fn set_speed_mode(&mut self, id: &str, mode: i32) -> Result<(), SumoError> {
        let f = self.api.set_speed_mode;
        self.with_id("setSpeedMode", id, |p| {
            // SAFETY: the pointer is a valid C string for the call.
            unsafe { f(p, mode) }
        })
    }

    /// Colours a vehicle as sumo-gui draws it (RGB, 0-255).
    pub fn set_color(&mut self, id: &str, [r, g, b]: [u8; 3]) -> Result<(), SumoError> {
        let f = self.api.set_color;
        self.with_id("setColor", id, |p| {
            // SAFETY: the pointer is a valid C string for the call.
            unsafe { f(p, c_int::from(r), c_int::from(g), c_int::from(b)) }
        })
    }

    /// Sets SUMO's lane-change mode bits.
    pub fn set_lane_change_mode(&mut self, id: &str, mode: i32) -> Result<(), SumoError> {
        let f = self.api.set_lane_change_mode;
        self.with_id("setLaneChangeMode", id, |p| {
            // SAFETY: the pointer is a valid C string for the call.
            unsafe { f(p, mode) }
        })
    }

    /// Asks the vehicle to change to `lane` (index on its edge) for `duration` seconds.
    pub fn change_lane(&mut self, id: &str, lane: i32, duration: f64) -> Result<(), SumoError> {
        let f = self.api.change_lane;
        self.with_id("changeLane", id, |p| {
            // SAFETY: the pointer is a valid C string for the call.
            unsafe { f(p, lane, duration) }
        })
    }

    /// Moves a vehicle to `pos` (front bumper, m) on `lane`; a vehicle added but not yet
    /// inserted (for example refused by SUMO's insertion checks) is inserted there.
    pub fn move_to(&mut self, id: &str, lane: &str, pos: f64) -> Result<(), SumoError> {
        let f = self.api.move_to;
        let lane = cstring(lane)?;
        self.with_id("moveTo", id, |p| {
            // SAFETY: both pointers are valid C strings for the call.
            unsafe { f(p, lane.as_ptr(), pos) }
        })
    }

    /// Adds a route made of `edges`.
    pub fn add_route(&mut self, id: &str, edges: &[&str]) -> Result<(), SumoError> {
        let owned = edges.iter().map(|e| cstring(e)).collect::<Result<Vec<_>, _>>()?;
        let ptrs: Vec<*const c_char> = owned.iter().map(|c| c.as_ptr()).collect();
        let f = self.api.route_add;
        self.with_id("route add", id, |p| {
            // SAFETY: the id and every edge pointer are valid C strings that outlive the call.
            unsafe { f(p, ptrs.as_ptr(), ptrs.len()) }
        })
    }

    /// Adds a vehicle; lane, position and speed use SUMO's depart attribute syntax.
    pub fn add_vehicle(&mut self, v: &NewVehicle<'_>) -> Result<(), SumoError> {
        let fields = [v.route, v.vtype, "now", v.lane, v.pos, v.speed]
            .iter()
            .map(|s| cstring(s))
            .collect::<Result<Vec<_>, _>>()?;
        let f = self.api.vehicle_add;
        self.with_id("vehicle add", v.id, |p| {
            // SAFETY: all seven pointers are valid C strings for the call.
            unsafe {
                f(
                    p,
                    fields[0].as_ptr(),
                    fields[1].as_ptr(),
                    fields[2].as_ptr(),
                    fields[3].as_ptr(),
                    fields[4].as_ptr(),
                    fields[5].as_ptr(),
                )
            }
        })
    }

    /// Closes the simulation (or detaches from a shared one) and reports SUMO's error, if any.
    pub fn close(mut self) -> Result<(), SumoError> {
        self.closed = true;
        // SAFETY: no pointers; errors come back as a return code.
        let rc = unsafe { (self.api.close)() };
        self.check("close", rc)
    }
}

/// A vehicle to insert now (see [`Sumo::add_vehicle`]).
#[derive(Debug, Clone, Copy)]
pub struct NewVehicle<'a> {
    /// Vehicle id.
    pub id: &'a str,
    /// Route id.
    pub route: &'a str,
    /// Vehicle type id.
    pub vtype: &'a str,
    /// departLane (an index, "best", ...).
    pub lane: &'a str,
    /// departPos (m, or "base", ...).
    pub pos: &'a str,
    /// departSpeed (m/s, or "max", ...).
    pub speed: &'a str,
}

impl Drop for Sumo {
    fn drop(&mut self) {
        if !self.closed {
            // SAFETY: no pointers; an error on close during drop has nowhere to go.
            let _ = unsafe { (self.api.close)() };
        }
        LIVE.store(false, Ordering::Release);
    }
}
