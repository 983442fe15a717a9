//! The Robotiq gripper's URCap socket (63352).

use super::*;

pub(super) fn gripper_connection(shared: &Shared, stream: TcpStream) -> io::Result<()> {
    let mut writer = stream.try_clone()?;
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    loop {
        line.clear();
        // Bounded: a client cannot make the controller buffer without end.
        if (&mut reader).take(4096).read_line(&mut line)? == 0 {
            return Ok(());
        }
        let reply = lock(&shared.ctl).robot.gripper.handle(line.trim());
        if shared.link_faults.gripper_muted.load(Ordering::Relaxed) {
            continue; // read, never answered
        }
        writer.write_all(reply.as_bytes())?;
        writer.write_all(b"\n")?;
    }
}
