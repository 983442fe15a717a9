//! The deployment file of a HIL mission's onboard processes.

use crate::mission::MissionSpec;

/// The deployment file the onboard processes of a HIL mission read (the format of
/// `grop_onboard::deployment`): the scene as the map, the run's clock, bus and namespace, and
/// the simulated UR5e's ports from the world's ready line.
pub(crate) fn deployment_for(
    spec: &MissionSpec,
    scene: &std::path::Path,
    robot: &std::path::Path,
    namespace: &str,
    clock: &str,
    bus: &str,
    field: &dyn Fn(&str) -> anyhow::Result<String>,
) -> anyhow::Result<String> {
    let quote = |p: &std::path::Path| format!("{:?}", p.display().to_string());
    Ok(format!(
        "# Written by the HIL mission runner for one closed-loop run.\n\
         namespace = {namespace:?}\n\
         map = {}\n\
         robot = {}\n\
         model = {}\n\
         can = \"vcan:{bus}\"\n\
         clock = {clock:?}\n\
         seed = {}\n\
         lidar = {:?}\n\
         {}\n\
         [inputs]\n\
         fixes = \"world\"\n\
         operator = \"world\"\n\n\
         [arm]\n\
         host = \"127.0.0.1\"\n\
         rtde_port = {}\n\
         dashboard_port = {}\n\
         script_port = {}\n\
         gripper_port = {}\n\n\
         [planner]\n\
         method = {:?}\n\
         paper_smp = {}\n\
         retry = {:?}\n",
        quote(scene),
        quote(robot),
        quote(&spec.model),
        spec.seed,
        match field("lidar")?.as_str() {
            "none" => "none".to_owned(),
            port => format!("udp:127.0.0.1:{port}"),
        },
        // The simulated sensor sends from loopback.
        match field("lidar")?.as_str() {
            "none" => "",
            _ => "lidar_sensor = \"127.0.0.1\"\n",
        },
        field("rtde")?,
        field("dashboard")?,
        field("secondary")?,
        field("gripper")?,
        spec.method,
        spec.paper_smp,
        spec.retry,
    ))
}
