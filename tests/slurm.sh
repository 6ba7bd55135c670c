#!/usr/bin/env bash
# Integration test of `nephele farm` on a real single-node Slurm cluster (issue 15).
#
# Starts munged, slurmctld and slurmd in the foreground (as background jobs of this script) with
# every file in a temporary folder, then:
#   1. renders the preview shot of scenes/duck-diffusion.ron locally, twice (renders must be
#      byte-identical across runs for the comparison below to mean anything);
#   2. submits the same preview shot as a 4-task array with `nephele farm --submit`, waits for it
#      (bounded), and checks that every frame exists once and equals the local render byte for
#      byte (and that the fitted target cache does too);
#   3. submits frames 1..4 of the preview as 2 tasks to an output folder whose name holds a
#      space, a quote, a `$(touch PWNED)`, a `;` and Slurm's `%j`, from the temporary folder,
#      and checks that the frames and the fit landed in that literal folder, that the logs are
#      at their literal paths (the folder's `%j` kept, Slurm's own `%j`, `%A_%a` expanded) and
#      that no `touch` ran;
#   4. submits frames 85..96 at full quality as 4 tasks of 3 frames, kills task 0 (SIGKILL) as
#      soon as its first frame is written (the kill lands mid-frame), requeues it with
#      `scontrol requeue`, and checks that it resumed (skipped the finished frame) and that the
#      frames again equal a local render;
# prints the wall times of the arrays and of the local renders, and stops every daemon it
# started by its PID on exit. With NEPHELE_SLURM_BENCH=1 it also times the whole shot at full
# quality as a 4-task array against a local render (a benchmark: minutes, not run by CI).
#
# Usage (as root): tests/slurm.sh [NEPHELE_BINARY]   (default: target/release/nephele)
# Without root or the Debian packages (slurmctld slurmd slurm-client munge) it prints
# "farm test skipped: <why>" and exits 0, or, under NEPHELE_REQUIRE_READERS=1 (as .ci/run sets:
# CI is root on a clean Debian that can install them), "farm test FAILED: <why>" and exits 1.
set -euo pipefail

repo=$(cd "$(dirname "$0")/.." && pwd)
bin=${1:-$repo/target/release/nephele}
scene=$repo/scenes/duck-diffusion.ron

skip() {
	if [ "${NEPHELE_REQUIRE_READERS:-}" = 1 ]; then
		echo "farm test FAILED: $* (NEPHELE_REQUIRE_READERS=1: Slurm must be there)" >&2
		exit 1
	fi
	echo "farm test skipped: $*"
	exit 0
}
fail() {
	echo "farm test FAILED: $*" >&2
	exit 1
}
now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }

[ "$(id -u)" = 0 ] || skip "needs root (munged runs as the munge user, slurmd as root)"
for c in munged slurmctld slurmd sbatch squeue scontrol setpriv; do
	command -v "$c" >/dev/null || skip "$c is not installed (apt-get install slurmctld slurmd slurm-client munge)"
done
id munge >/dev/null 2>&1 || skip "no munge user (install the munge package)"
[ -x "$bin" ] || fail "no nephele binary at $bin (run cargo build --release)"
bin=$(realpath "$bin")

tmp=$(mktemp -d /tmp/nephele-slurm.XXXXXX)
chmod 755 "$tmp"
pids=()
jobs_submitted=""

cleanup() {
	set +e
	if [ -n "$jobs_submitted" ]; then
		scancel $jobs_submitted 2>/dev/null
		for _ in $(seq 50); do
			[ -z "$(squeue -h -j "${jobs_submitted// /,}" 2>/dev/null)" ] && break
			sleep 0.2
		done
	fi
	# Stop the daemons newest first, by PID; SIGKILL what is still there after 10 s.
	for ((i = ${#pids[@]} - 1; i >= 0; i--)); do
		kill "${pids[i]}" 2>/dev/null
	done
	for p in "${pids[@]}"; do
		for _ in $(seq 50); do
			kill -0 "$p" 2>/dev/null || break
			sleep 0.2
		done
		kill -9 "$p" 2>/dev/null
		wait "$p" 2>/dev/null
	done
	rm -rf "$tmp"
}
trap cleanup EXIT

# wait_for SECONDS WHAT COMMAND...: poll COMMAND every 0.1 s until it succeeds.
wait_for() {
	local limit=$1 what=$2
	shift 2
	local start
	start=$(now)
	until "$@" >/dev/null 2>&1; do
		if awk -v a="$start" -v b="$(now)" -v l="$limit" 'BEGIN { exit !(b - a > l) }'; then
			fail "$what: not within $limit s"
		fi
		sleep 0.1
	done
}

# --- munge: a private key and socket in the temporary folder --------------------------------
# (the key's folder is private; the socket's must be searchable by everyone)
mkdir -p "$tmp/munge" "$tmp/munge-run"
head -c 1024 /dev/urandom >"$tmp/munge/munge.key"
chown -R munge:munge "$tmp/munge" "$tmp/munge-run"
chmod 700 "$tmp/munge"
chmod 755 "$tmp/munge-run"
chmod 400 "$tmp/munge/munge.key"
sock=$tmp/munge-run/munge.sock
setpriv --reuid=munge --regid=munge --init-groups munged -F --socket="$sock" \
	--key-file="$tmp/munge/munge.key" --log-file="$tmp/munge/munged.log" \
	--pid-file="$tmp/munge-run/munged.pid" --seed-file="$tmp/munge/munged.seed" \
	>"$tmp/munged.out" 2>&1 &
pids+=($!)
wait_for 10 "munged answering" bash -c "munge -S '$sock' -n | unmunge -S '$sock'"

# --- slurm: one node, two CPUs, no accounting. cred_expire (default 120 s) is also how long a
# requeued job waits before it may start again.
mkdir -p "$tmp/slurm/state" "$tmp/slurm/spool"
port=$((16000 + RANDOM % 4000))
export SLURM_CONF=$tmp/slurm/slurm.conf
cat >"$SLURM_CONF" <<EOF
ClusterName=nephele-test
SlurmctldHost=localhost(127.0.0.1)
SlurmUser=root
SlurmctldPort=$port
SlurmdPort=$((port + 1))
AuthType=auth/munge
AuthInfo=socket=$sock,cred_expire=10
CredType=cred/munge
StateSaveLocation=$tmp/slurm/state
SlurmdSpoolDir=$tmp/slurm/spool
SlurmctldPidFile=$tmp/slurm/slurmctld.pid
SlurmdPidFile=$tmp/slurm/slurmd.pid
SlurmctldLogFile=$tmp/slurm/slurmctld.log
SlurmdLogFile=$tmp/slurm/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
NodeName=localhost NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN
PartitionName=render Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -D -f "$SLURM_CONF" >"$tmp/slurm/slurmctld.out" 2>&1 &
pids+=($!)
wait_for 30 "slurmctld answering" scontrol ping
slurmd -D -N localhost -f "$SLURM_CONF" >"$tmp/slurm/slurmd.out" 2>&1 &
pids+=($!)
wait_for 30 "node localhost idle" bash -c '[ "$(sinfo -h -o %T)" = idle ]'
echo "slurm is up: slurmctld, slurmd and munged started by this script (PIDs ${pids[*]})"

# job_ids FARM_OUTPUT: "prepare array" from `nephele farm --submit`'s output.
job_ids() {
	local prep arr
	prep=$(sed -n 's/^prepare job: \([0-9]*\)$/\1/p' <<<"$1")
	arr=$(sed -n 's/^render array: \([0-9]*\) .*/\1/p' <<<"$1")
	[ -n "$prep" ] && [ -n "$arr" ] || fail "no job ids in the output of nephele farm:
$1"
	echo "$prep $arr"
}

# wait_jobs SECONDS IDS...: wait until squeue no longer lists the jobs.
wait_jobs() {
	local limit=$1
	shift
	local ids="$*"
	wait_for "$limit" "jobs $ids finished" bash -c "[ -z \"\$(squeue -h -j ${ids// /,})\" ]"
}

# check_completed ARRAY TASKS: every task COMPLETED with exit code 0.
check_completed() {
	local info
	info=$(scontrol -o show job "$1")
	local done
	done=$(grep -c 'JobState=COMPLETED .*ExitCode=0:0' <<<"$info" || true)
	[ "$done" = "$2" ] || fail "array $1: $done of $2 tasks completed:
$info"
}

# same_frames DIR_A DIR_B FIRST LAST: both folders hold exactly frames FIRST..LAST (EXR, PNG
# and the frame's manifest), byte-identical.
same_frames() {
	local a=$1 b=$2 n=0
	for ((f = $3; f <= $4; f++)); do
		for ext in exr png manifest.json; do
			local name
			name=$(printf 'duck-diffusion_%04d.%s' "$f" "$ext")
			[ -f "$a/$name" ] || fail "$a/$name is missing"
			[ -f "$b/$name" ] || fail "$b/$name is missing"
			cmp -s "$a/$name" "$b/$name" || fail "$a/$name differs from $b/$name"
			n=$((n + 1))
		done
	done
	for d in "$a" "$b"; do
		local count
		count=$(find "$d" -maxdepth 1 -name 'duck-diffusion_*.*' | wc -l)
		[ "$count" = "$n" ] || fail "$d holds $count frame files, expected $n"
	done
}

# --- 1. local preview render, twice --------------------------------------------------------
t=$(now)
"$bin" prepare "$scene" --preview --output "$tmp/local" 2>/dev/null
"$bin" render "$scene" --preview --output "$tmp/local" 2>/dev/null
local_preview=$(since "$t")
# The shot's length comes from the scene: count the frames the local render wrote.
total=$(find "$tmp/local/preview" -maxdepth 1 -name 'duck-diffusion_*.exr' | wc -l)
[ "$total" -ge 4 ] && [ $((total % 4)) = 0 ] || fail "the preview shot has $total frames: expected a multiple of 4"
chunk=$((total / 4))
"$bin" prepare "$scene" --preview --output "$tmp/local2" 2>/dev/null
"$bin" render "$scene" --preview --output "$tmp/local2" 2>/dev/null
same_frames "$tmp/local/preview" "$tmp/local2/preview" 1 "$total"
cmp -s "$tmp"/local/target-*.ron "$tmp"/local2/target-*.ron || fail "two fits differ"
echo "local renders are byte-identical across runs ($total preview frames, EXR and PNG, and the fit)"

# --- 2. the preview shot as a 4-task array -------------------------------------------------
# (the farm's output folder has a space in its name: the job scripts must quote their paths)
farm="$tmp/farm out"
t=$(now)
out=$("$bin" farm "$scene" --engine slurm --chunk "$chunk" --preview --output "$farm" --submit)
read -r prep arr <<<"$(job_ids "$out")"
jobs_submitted="$prep $arr"
grep -q "^4 tasks" <<<"$out" || fail "expected 4 tasks:
$out"
wait_jobs 300 "$prep" "$arr"
farm_preview=$(since "$t")
check_completed "$prep" 1
check_completed "$arr" 4
same_frames "$tmp/local/preview" "$farm/preview" 1 "$total"
cmp -s "$tmp"/local/target-*.ron "$farm"/target-*.ron || fail "the farm's fit differs from the local one"
for i in 0 1 2 3; do
	grep -q "^$farm/preview: $chunk frames rendered, 0 already done" \
		"$farm/preview/logs/duck-diffusion-preview_${arr}_$i.log" ||
		fail "task $i did not render $chunk frames: $(cat "$farm/preview/logs/duck-diffusion-preview_${arr}_$i.log")"
done
echo "array $arr: 4 tasks completed; $total preview frames equal the local render byte for byte"

# --- 3. an output folder a shell would run and Slurm would expand --------------------------
# The job files must give nephele the folder word for word and Slurm's --output its name with
# `%` doubled; the jobs start in $tmp (sbatch's working folder), where an injected `touch`
# would leave PWNED.
hostile="$tmp/it's \$(touch PWNED) %j; farm"
t=$(now)
out=$(cd "$tmp" && "$bin" farm "$scene" --engine slurm --frames 1..4 --chunk 2 --preview \
	--output "$hostile" --submit)
read -r prep arr <<<"$(job_ids "$out")"
jobs_submitted="$prep $arr"
grep -q "^2 tasks" <<<"$out" || fail "expected 2 tasks:
$out"
# (bounded tighter than the others: it takes about 10 s)
wait_jobs 120 "$prep" "$arr"
farm_hostile=$(since "$t")
check_completed "$prep" 1
check_completed "$arr" 2
for f in 1 2 3 4; do
	for ext in exr png manifest.json; do
		name=$(printf 'duck-diffusion_%04d.%s' "$f" "$ext")
		cmp -s "$tmp/local/preview/$name" "$hostile/preview/$name" ||
			fail "$hostile/preview/$name is missing or differs from the local render: $(find "$tmp" -name "$name")"
	done
done
count=$(find "$hostile/preview" -maxdepth 1 -name 'duck-diffusion_*.*' | wc -l)
[ "$count" = 12 ] || fail "$hostile/preview holds $count frame files, expected 12"
cmp -s "$tmp"/local/target-*.ron "$hostile"/target-*.ron || fail "the fit is not in $hostile"
logs=$hostile/preview/logs
[ -f "$logs/duck-diffusion-preview-prepare_$prep.log" ] ||
	fail "the prepare job's log is not in $logs: $(find "$tmp" -name '*-prepare_*.log')"
for i in 0 1; do
	grep -qF "$hostile/preview: 2 frames rendered, 0 already done" \
		"$logs/duck-diffusion-preview_${arr}_$i.log" ||
		fail "task $i's log is not in $logs or did not render 2 frames: $(find "$tmp" -name "*_${arr}_$i.log")"
done
pwned=$(find "$tmp" "$repo" -maxdepth 1 -name 'PWNED*')
pwned+=$(find "$hostile" -name 'PWNED*')
[ -z "$pwned" ] || fail "a job ran the \$(touch PWNED) in the folder's name: $pwned"
echo "array $arr: 2 tasks wrote frames 1..4, the fit and the logs in the literal folder ${hostile#"$tmp"/}; nothing in its name ran"

# --- 4. kill a task mid-frame, requeue it, check it resumes --------------------------------
t=$(now)
"$bin" render "$scene" --frames 85..96 --output "$tmp/local" 2>/dev/null
local_full=$(since "$t")
t=$(now)
out=$("$bin" farm "$scene" --engine slurm --frames 85..96 --chunk 3 --output "$farm" --submit)
read -r prep arr <<<"$(job_ids "$out")"
jobs_submitted="$prep $arr"
# Task 0 renders frames 85..87: SIGKILL it as soon as frame 85 is finished (its manifest is
# written last), so the kill lands while it renders frame 86; then requeue the failed task.
wait_for 120 "task 0's first frame" test -f "$farm/duck-diffusion_0085.manifest.json"
# The batch script execs nephele, so the batch step's nephele process is the task.
task0=$(scontrol -o show job "${arr}_0" | sed -n 's/^JobId=\([0-9]*\) .*/\1/p')
victim=""
for p in $(scontrol listpids "$task0" 2>/dev/null | awk '$3 == "batch" { print $1 }'); do
	[ "$(cat "/proc/$p/comm" 2>/dev/null)" = nephele ] && victim=$p
done
[ -n "$victim" ] || fail "no nephele process in task 0 (job $task0): $(scontrol listpids "$task0" 2>&1)"
kill -9 "$victim"
for _ in $(seq 300); do
	state=$(scontrol -o show job "${arr}_0" | grep -o 'JobState=[A-Z_]*')
	case $state in JobState=RUNNING | JobState=COMPLETING) ;; *) break ;; esac
	sleep 0.1
done
[ "$state" = JobState=FAILED ] || fail "task 0 is not FAILED after SIGKILL: $(scontrol -o show job "${arr}_0")
$(cat "$farm/logs/duck-diffusion_${arr}_0.log")"
[ ! -e "$farm/duck-diffusion_0087.manifest.json" ] || fail "task 0 had finished its chunk before the kill"
scontrol requeue "${arr}_0"
wait_jobs 300 "$prep" "$arr"
farm_full=$(since "$t")
check_completed "$arr" 4
grep -q "Restarts=1" <<<"$(scontrol -o show job "${arr}_0")" || fail "task 0 was not requeued"
log0=$farm/logs/duck-diffusion_${arr}_0.log
summaries=$(grep -c "frames rendered" "$log0" || true)
[ "$summaries" = 1 ] || fail "task 0 finished $summaries times (expected the killed run to stop early):
$(cat "$log0")"
resumed=$(sed -n 's/.*: \([0-9]*\) frames rendered, \([0-9]*\) already done.*/\1 \2/p' "$log0")
read -r rendered skipped <<<"$resumed"
[ "$((rendered + skipped))" = 3 ] && [ "$skipped" -ge 1 ] && [ "$skipped" -le 2 ] ||
	fail "task 0 did not resume mid-chunk (rendered $rendered, skipped $skipped):
$(cat "$log0")"
# Across the killed and the requeued run, every frame of the chunk was finished exactly once.
for f in 85 86 87; do
	[ "$(grep -c "^frame *$f/$total:" "$log0")" = 1 ] || fail "frame $f was not rendered exactly once by task 0:
$(cat "$log0")"
done
same_frames "$tmp/local" "$farm" 85 96
echo "array $arr: task 0 killed mid-frame and requeued; it resumed ($skipped frames already done, $rendered rendered); frames 85..96 equal the local render byte for byte"
echo "task 0's log (both runs):"
sed 's/^/  | /' "$log0"

# --- 5. (benchmark, NEPHELE_SLURM_BENCH=1) the whole shot at full quality ------------------
if [ "${NEPHELE_SLURM_BENCH:-0}" = 1 ]; then
	t=$(now)
	"$bin" prepare "$scene" --output "$tmp/bench-local" 2>/dev/null
	"$bin" render "$scene" --output "$tmp/bench-local" 2>/dev/null
	local_bench=$(since "$t")
	t=$(now)
	out=$("$bin" farm "$scene" --engine slurm --chunk "$chunk" --output "$tmp/bench-farm" --submit)
	read -r prep arr <<<"$(job_ids "$out")"
	jobs_submitted="$prep $arr"
	wait_jobs 1800 "$prep" "$arr"
	farm_bench=$(since "$t")
	check_completed "$arr" 4
	same_frames "$tmp/bench-local" "$tmp/bench-farm" 1 "$total"
	echo "wall time: whole shot at full quality ($total frames, 640x360) 4-task array ${farm_bench} s vs local ${local_bench} s (both include the fit); frames equal"
fi

echo "wall time: preview shot ($total frames, 160x90) 4-task array ${farm_preview} s vs local ${local_preview} s (both include the fit)"
echo "wall time: preview frames 1..4 in the hostile folder, 2-task array ${farm_hostile} s (with the fit)"
echo "wall time: full quality frames 85..96 (640x360) 4-task array with one requeue ${farm_full} s vs local ${local_full} s (target cached)"
echo "farm test passed"
