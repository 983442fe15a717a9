//! CAN bus trait with SocketCAN and iceoryx2 virtual-bus backends.
