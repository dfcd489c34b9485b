//! Many SUMO scenarios: route files from a demand description (`routes`, reading its base
//! file with `route_base`), the batch runner with one worker process per run (`runner`), and
//! per-run results with their summary and the merge of shards (`summary`), and the summary as
//! charts (`plots`); the penetration study over SUMO's outputs (`penetration`) and the merge's
//! capacity (`capacity`).

pub mod capacity;
pub mod penetration;
pub mod plots;
mod route_base;
pub mod routes;
pub mod runner;
pub mod summary;
