"""Live links to other programs: FlightGear's native-fdm stream, X-Plane's UDP interface and Tacview's
real-time telemetry. Every socket binds to loopback unless told otherwise."""
