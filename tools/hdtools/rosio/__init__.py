"""The joint's data in the robot stack's formats: MCAP files and rosbag2
folders in and out, and a live Foxglove WebSocket view (docs/how-to/ros2.md).

Library choice: `rosbags` writes and reads both (rosbag2 folders with
mcap or sqlite3 storage, bare .mcap files), serializes CDR from its own
copy of the ROS 2 message definitions and needs no ROS install, so one
library serves the monitor, `canlog convert` and `analyze`.  `mcap` and
`mcap-ros2-support` (the MCAP project's own reader and CDR decoder) are
the independent readers the tests check our files with; `foxglove-sdk`
serves the live view (an optional extra: imported only by --foxglove).

  topics     topic names and message types, derived from the DBC's signals
  messages   one telemetry sample -> ROS 2 messages (JointState, Float64,
             DiagnosticArray)
  bagout     a .mcap file or rosbag2 folder written under a temporary name
  stream     the monitor's decoded frames -> samples (causal angles)
  convert    a decoded candump log -> samples (angles from TELEM_C counts)
  bagin      a bag -> the analysis log columns (the log contract)
  live       the Foxglove WebSocket server
  cli        the options of monitor / canlog convert, and canlog convert
  bench      recording cost and analyze on MCAP vs CSV (docs/how-to/ros2.md)
"""
