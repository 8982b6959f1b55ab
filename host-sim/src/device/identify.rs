//! `host-sim device --port PORT identify [--machine M.toml [--write OUT.toml]]
//! [--format table|json]`: the device measures its motors
//! (`shared::controller::identify`) through the procedure runner; the result is
//! printed and written by [`crate::identity`].

use shared::controller::identify::{IdentifyReport, IdentifyStatus};
use shared::protocol::{Request, Response};

use super::args::IdentifyArgs;
use super::procedure::{self, Procedure, Stage};
use crate::failure::{Console, Failure};
use crate::identity::{conclude, Prepared};
use crate::link::client::Client;
use crate::link::requests::{ask, unexpected};

/// The identification, for [`procedure::run`].
const IDENTIFY: Procedure<IdentifyReport> = Procedure {
    name: "identification",
    last: "the last identification's",
    start: Request::RunIdentify,
    read: read_identify,
    stage: identify_stage,
};

fn read_identify(client: &mut Client) -> Result<IdentifyReport, Failure> {
    match ask(client, &Request::ReadIdentify)? {
        Response::Identify(r) => Ok(r),
        other => Err(unexpected(&Request::ReadIdentify, &other)),
    }
}

fn identify_stage(r: &IdentifyReport) -> Stage {
    match r.status {
        IdentifyStatus::NotRun => Stage::NotRun,
        IdentifyStatus::Running => Stage::Running,
        IdentifyStatus::Done => Stage::Done,
        IdentifyStatus::Aborted => Stage::Aborted,
    }
}

/// Runs it on the device, prints the result and writes `--write`.
pub fn run(
    client: &mut Client,
    a: &IdentifyArgs,
    prepared: Prepared,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let report = procedure::run(client, &IDENTIFY, a.timeout)?;
    conclude(&report, prepared, a.format, out)
}
