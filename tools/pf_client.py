#!/usr/bin/python3
"""pf_client.py — scripted submission and progressive retrieval with Python (Debian's
python3-grpcio + python3-protobuf).

    tools/pf_client.py scenes/cornell-box/cornell-box.json --coordinator 127.0.0.1:7000 \\
        --res 64x64 --photons 20000 --stride 2 --rounds 4 -o cornell.exr

Uploads the scene folder (every file under the entry's folder, as `pf` does), submits a
photon-map skipping job that uses the scene's own camera at the requested resolution, follows
WatchJob and rewrites the output EXR atomically with every image snapshot, then saves the final
image from GetImage. Prints one line per update and the job id last. Exit 0 when the job
succeeded, 1 otherwise, 2 on bad arguments.

The Python stubs are generated from proto/photonfarm/v1/farm.proto by the build (target
pf_python_stubs: protoc --python_out + grpc_python_plugin, into build/client/python); pass
--stubs DIR or set PF_PY_STUBS if they are elsewhere. Without them, this script generates them
itself with protoc and grpc_python_plugin (Debian: protobuf-compiler, protobuf-compiler-grpc).
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load_stubs(stubs_dir):
    candidates = [stubs_dir, os.environ.get("PF_PY_STUBS"), os.path.join(REPO, "build", "client", "python")]
    for d in candidates:
        if d and os.path.exists(os.path.join(d, "photonfarm", "v1", "farm_pb2_grpc.py")):
            sys.path.insert(0, d)
            break
    else:
        d = os.path.join(os.path.expanduser("~"), ".cache", "photonfarm", "python-stubs")
        os.makedirs(d, exist_ok=True)
        subprocess.run(["protoc", "--proto_path", os.path.join(REPO, "proto"), "--python_out", d, "--grpc_out", d,
                        "--plugin=protoc-gen-grpc=" + "/usr/bin/grpc_python_plugin",
                        os.path.join(REPO, "proto", "photonfarm", "v1", "farm.proto")], check=True)
        sys.path.insert(0, d)
    from photonfarm.v1 import farm_pb2, farm_pb2_grpc  # noqa: E402
    return farm_pb2, farm_pb2_grpc


def collect_bundle(pb, entry):
    """The entry file plus every file under its folder (common/scene/scene_bundle.h's rule)."""
    root = os.path.dirname(os.path.abspath(entry))
    bundle = pb.SceneBundle(entry=os.path.basename(entry))
    for folder, _, files in sorted(os.walk(root)):
        for name in sorted(files):
            path = os.path.join(folder, name)
            with open(path, "rb") as f:
                bundle.files.add(path=os.path.relpath(path, root).replace(os.sep, "/"), content=f.read())
    return bundle


def write_atomically(path, data):
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".pf_client.")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", help="scene manifest (.json), .mgf or .obj")
    ap.add_argument("--coordinator", default=os.environ.get("PF_COORDINATOR"), help="HOST:PORT")
    ap.add_argument("--token-file", help="client bearer token file, one line (default: $PF_TOKEN)")
    ap.add_argument("--tls-ca", default=os.environ.get("PF_TLS_CA"),
                    help="PEM roots of the coordinator's certificate: connect with TLS (default: $PF_TLS_CA)")
    ap.add_argument("--tls-cert", default=os.environ.get("PF_TLS_CERT"), help="PEM client certificate (mTLS)")
    ap.add_argument("--tls-key", default=os.environ.get("PF_TLS_KEY"), help="PEM private key of --tls-cert")
    ap.add_argument("--stubs", help="folder with photonfarm/v1/farm_pb2*.py")
    ap.add_argument("-o", "--output", required=True, help="EXR kept up to date while the job runs")
    ap.add_argument("--res", default="64x64", help="WxH")
    ap.add_argument("--photons", type=int, default=20000)
    ap.add_argument("--k", type=int, default=50)
    ap.add_argument("--stride", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--interval", type=float, default=0.2, help="minimum seconds between updates")
    ap.add_argument("--timeout", type=float, default=60, help="deadline of each call, seconds")
    a = ap.parse_args()
    if not a.coordinator:
        ap.error("--coordinator is required (or set PF_COORDINATOR)")
    try:
        width, height = (int(v) for v in a.res.lower().split("x"))
    except ValueError:
        ap.error("--res: expected WxH")

    pb, rpc = load_stubs(a.stubs)
    import grpc  # Debian: python3-grpcio

    # The token rules of rpc/grpc_channel.h ParseToken: trimmed, one line of printable ASCII.
    if a.token_file:
        with open(a.token_file) as f:
            token, source = f.read().strip(), "--token-file"
    else:
        token, source = os.environ.get("PF_TOKEN"), "$PF_TOKEN"
        token = None if token is None else token.strip()
    if token is not None and (not token or len(token) > 4096 or
                              any(not (0x21 <= ord(c) <= 0x7e) for c in token)):
        ap.error(f"{source}: the token must be one non-empty line of printable ASCII without spaces")
    metadata = [("authorization", "Bearer " + token)] if token else []
    options = [("grpc.keepalive_time_ms", 10000), ("grpc.max_receive_message_length", -1),
               ("grpc.max_send_message_length", -1)]
    if bool(a.tls_cert) != bool(a.tls_key):
        ap.error("--tls-cert and --tls-key go together")
    if a.tls_ca:
        def read(path):
            with open(path, "rb") as f:
                return f.read()
        creds = grpc.ssl_channel_credentials(read(a.tls_ca), read(a.tls_key) if a.tls_key else None,
                                             read(a.tls_cert) if a.tls_cert else None)
        channel = grpc.secure_channel(a.coordinator, creds, options=options)
    else:
        channel = grpc.insecure_channel(a.coordinator, options=options)
    render = rpc.RenderServiceStub(channel)
    try:
        up = render.UploadScene(pb.UploadSceneRequest(bundle=collect_bundle(pb, a.scene)),
                                timeout=a.timeout, metadata=metadata)
        print(f"scene {up.scene_hash[:12]}: {up.triangles} triangles, {up.lights} lights", flush=True)
        spec = pb.JobSpec(
            name=os.path.basename(a.scene), scene_hash=up.scene_hash, seed=a.seed,
            camera=pb.Camera(width=width, height=height),  # only the size: the scene's own camera
            settings=pb.RenderSettings(integrator=pb.INTEGRATOR_PHOTONMAP,
                                       photon_map=pb.PhotonMapSettings(photons=a.photons, k=a.k)),
            plan=pb.Plan(skipping=pb.Skipping(stride=a.stride, rounds=a.rounds, samples_per_pixel=a.spp)))
        job_id = render.SubmitJob(pb.SubmitJobRequest(spec=spec), timeout=a.timeout, metadata=metadata).job_id
        print(f"job {job_id} submitted", flush=True)

        snapshots = 0
        start = time.time()
        final = None
        chunks = []  # a snapshot over 1 MiB arrives as consecutive updates, one chunk each
        # The watch lasts as long as the job; its deadline only bounds a stuck stream.
        for update in render.WatchJob(pb.WatchJobRequest(job_id=job_id, include_images=True,
                                                         min_interval_seconds=a.interval),
                                      timeout=7 * 24 * 3600, metadata=metadata):
            st = update.status
            if update.HasField("image") and update.image.exr_bytes:
                if update.image.index == 0:
                    chunks = []
                chunks.append(update.image.exr_bytes)
                if update.image.index + 1 < update.image.count:
                    continue
                write_atomically(a.output, b"".join(chunks))
                snapshots += 1
            noise = f"{st.estimated_noise_rms:.4g}" if st.estimated_noise_rms >= 0 else "-"
            print(f"{time.time() - start:6.2f}s {pb.JobState.Name(st.state)} {st.tasks_done}/{st.tasks_total} "
                  f"tasks, noise {noise}, snapshots {snapshots}", flush=True)
            final = st
        # The final image, reassembled from its chunks.
        chunks = list(render.GetImage(pb.GetImageRequest(job_id=job_id), timeout=a.timeout, metadata=metadata))
        write_atomically(a.output, b"".join(c.exr_bytes for c in sorted(chunks, key=lambda c: c.index)))
    except grpc.RpcError as e:
        print(f"error: {e.code().name}: {e.details()}", file=sys.stderr)
        return 1
    ok = final is not None and final.state == pb.JOB_STATE_SUCCEEDED
    print(f"{job_id} {'succeeded' if ok else 'did not succeed'}: {snapshots} snapshots -> {a.output}")
    print(job_id)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
