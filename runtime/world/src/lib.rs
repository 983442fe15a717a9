//! Dinner-table world: scene and robot files, generators, occupancy grid, A*, overhead rendering.
