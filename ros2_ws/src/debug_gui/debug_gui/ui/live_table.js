// A table the server patches cell by cell (see _live_table.py for why), drawn with plain
// <tr>/<td> in Quasar's table classes rather than by a QTable: a QTable re-renders every row
// and a QTd component per slotted cell whenever one cell changes. Here each row is
// memoised (v-memo on its version), so a patch re-renders only the rows it touched, and
// the patches of every table on the page that arrive within the same second are applied
// together at the second's end: one render, not one per table. The rows' box is contained
// (CSS `contain: strict`, its height set from the table's), so a changed cell lays out its
// own table, not the page around it (a page layout was most of an update's cost).
// Rows out of sight (scrolled away, an IntersectionObserver says) keep their new figures
// unrendered until they come into sight: with three robots' tables of 40 callbacks, most
// rows are below the window, and a loaded machine's browser spent its time on them.

// Tables with patches waiting, and the one timer that applies them all.
const waiting = new Set();
let flushTimer = null;

function flushAll() {
  flushTimer = null;
  for (const table of waiting) table.applyWaiting();
  waiting.clear();
}

export default {
  template: `
    <div :class="containerClass">
      <div class="text-caption" :data-testid="captionTestid">{{ text }}</div>
      <div ref="middle" class="q-table__middle scroll"
           :style="{ contain: 'strict', height: height + 'px' }">
        <table ref="table" class="q-table">
          <thead><tr>
            <th v-for="c in cols" :key="c.name" :class="thClass(c)" :style="c.headerStyle"
                @click="c.sortable && sort(c.name)"><i v-if="c.sortable && right(c)"
                class="q-icon notranslate material-icons q-table__sort-icon
                q-table__sort-icon--right" aria-hidden="true">arrow_upward</i>{{ c.label
              }}<i v-if="c.sortable && !right(c)" class="q-icon notranslate material-icons
                q-table__sort-icon q-table__sort-icon--left" aria-hidden="true"
                >arrow_upward</i></th>
          </tr></thead>
          <tbody>
            <tr v-for="row in sorted" :key="row[rowKey]" v-memo="[row.__v, colsKey]"
                :data-row="row[rowKey]">
              <td v-for="c in cols" :key="c.name" :class="'text-' + (c.align || 'right')"
                  :style="c.style" :title="c.cell === 'titled' ? row[c.field] : undefined">
                <span v-if="c.cell === 'badge' && row[c.field]"
                      class="q-badge flex inline items-center q-badge--multi-line
                      bg-negative text-white" role="status"
                      style="word-break: keep-all; text-align: center">{{ row[c.field] }}</span>
                <template v-else-if="c.cell === 'titled'"><template
                  v-for="part in parts(row[c.field])">{{ part }}<wbr></template></template>
                <template v-else-if="c.cell !== 'badge'">{{ row[c.field] }}</template>
              </td>
            </tr>
          </tbody>
        </table>
      </div>
    </div>
  `,
  props: {
    rows: Array,
    columns: Array,
    rowKey: String,
    pagination: Object,
    visibleColumns: Array,
    dense: Boolean,
    flat: Boolean,
    wrapCells: Boolean, // cells wrap here anyway: declared so it is no attribute
    caption: String,
    captionTestid: String,
  },
  data() {
    return {
      version: 0,
      sortBy: this.pagination?.sortBy ?? null,
      descending: Boolean(this.pagination?.descending),
      visible: this.visibleColumns,
      text: this.caption,
      height: 0,
    };
  },
  created() {
    // Not reactive on purpose: a patch bumps `version` once, whatever it touched.
    this.store = new Map();
    this.seq = 0;
    this.pending = [];
    // Keys (as text) of rows out of sight, and of those among them whose figures changed.
    this.away = new Set();
    this.stale = new Set();
    this.watched = new WeakSet();
    this.load(this.rows);
  },
  mounted() {
    this.sight = new IntersectionObserver((entries) => this.onSight(entries),
                                          { rootMargin: "200px" });
    this.watchRows();
    // The rows' box is sized by hand, so that a changed cell lays out this table only
    // (CSS containment) instead of the whole page; its height follows the table's.
    this.observer = new ResizeObserver(() => {
      const middle = this.$refs.middle;
      const bar = middle.offsetHeight - middle.clientHeight; // a horizontal scroll bar
      this.height = this.$refs.table.offsetHeight + bar;
    });
    this.observer.observe(this.$refs.table);
  },
  updated() {
    this.watchRows();
  },
  unmounted() {
    this.observer.disconnect();
    this.sight.disconnect();
    waiting.delete(this);
  },
  computed: {
    containerClass() {
      return "q-table__container q-table--horizontal-separator column no-wrap" +
        (this.flat ? " q-table--flat" : "") + (this.dense ? " q-table--dense" : "");
    },
    cols() {
      const shown = this.visible ? new Set(this.visible) : null;
      return this.columns.filter((c) => !shown || c.required || shown.has(c.name));
    },
    colsKey() {
      return this.cols.map((c) => c.name).join(",");
    },
    sorted() {
      this.version; // recomputed on every applied patch
      const rows = [...this.store.values()];
      const by = this.sortBy;
      if (by === null) return rows;
      const field = this.columns.find((c) => c.name === by)?.field ?? by;
      const dir = this.descending ? -1 : 1;
      return rows.sort((a, b) => dir * compare(a[field], b[field]));
    },
  },
  watch: {
    // The server re-sent the whole element (a column switch, a reconnect): start over.
    rows(rows) {
      this.load(rows);
    },
    caption(text) {
      this.text = text;
    },
    visibleColumns(columns) {
      this.visible = columns;
    },
  },
  methods: {
    right(c) {
      return (c.align || "right") === "right";
    },
    thClass(c) {
      const sorted = c.name === this.sortBy;
      return "text-" + (c.align || "right") + (c.sortable ? " sortable" : "") +
        (sorted ? " sorted" : "") + (sorted && this.descending ? " sort-desc" : "");
    },
    sort(name) {
      // A new column sorts ascending; the sorted one turns around.
      this.descending = name === this.sortBy ? !this.descending : false;
      this.sortBy = name;
    },
    parts(value) {
      return String(value).split(/(?<=[/._])/);
    },
    // Rows rendered since the last look are watched for coming into and out of sight.
    watchRows() {
      for (const tr of this.$refs.table.tBodies[0]?.rows ?? []) {
        if (!this.watched.has(tr)) {
          this.watched.add(tr);
          this.sight.observe(tr);
        }
      }
    },
    onSight(entries) {
      let shown = false;
      for (const entry of entries) {
        const key = entry.target.dataset.row;
        if (!entry.target.isConnected) {
          this.sight.unobserve(entry.target);
        } else if (!entry.isIntersecting) {
          this.away.add(key);
        } else {
          this.away.delete(key);
          if (this.stale.delete(key)) {
            const row = this.store.get(this.keyOf(key));
            if (row) row.__v = ++this.seq;
            shown = true;
          }
        }
      }
      if (shown) this.version++;
    },
    // The store's key for a row's text key (row keys may be numbers).
    keyOf(text) {
      for (const k of this.store.keys()) if (String(k) === text) return k;
      return text;
    },
    load(rows) {
      this.stale.clear();
      this.store.clear();
      for (const row of rows || []) this.store.set(row[this.rowKey], { ...row, __v: ++this.seq });
      this.version++;
    },
    setVisible(columns) {
      this.visible = columns;
    },
    // changes: {set: [partial rows, each with its key], remove: [keys], caption?: the
    // line above the table (a status: part of the same render)}. The first rows
    // are shown at once; later changes wait for the other tables' (see the top).
    patch(changes) {
      if (this.store.size === 0) {
        this.apply(changes);
        return;
      }
      this.pending.push(changes);
      waiting.add(this);
      if (flushTimer === null) flushTimer = setTimeout(flushAll, 1000 - (Date.now() % 1000));
    },
    applyWaiting() {
      for (const changes of this.pending.splice(0)) this.apply(changes);
    },
    apply(changes) {
      const key = this.rowKey;
      let render = changes.remove.length > 0;
      if (changes.caption !== undefined && changes.caption !== this.text) {
        this.text = changes.caption;
      }
      for (const gone of changes.remove) {
        this.store.delete(gone);
        this.stale.delete(String(gone));
      }
      for (const part of changes.set) {
        const row = this.store.get(part[key]);
        if (!row) {
          this.store.set(part[key], { ...part, __v: ++this.seq });
          render = true;
        } else if (this.away.has(String(part[key]))) {
          Object.assign(row, part); // drawn when it comes into sight
          this.stale.add(String(part[key]));
        } else {
          Object.assign(row, part, { __v: ++this.seq });
          render = true;
        }
      }
      // Sorted by a column, a change out of sight may still move a row into sight.
      if (render || (this.sortBy !== null && changes.set.length)) this.version++;
    },
  },
};

// Quasar's order: numbers by value, anything else as lower-case text.
function compare(a, b) {
  if (typeof a === "number" && typeof b === "number") return a - b;
  const [x, y] = [String(a ?? "").toLowerCase(), String(b ?? "").toLowerCase()];
  return x < y ? -1 : x > y ? 1 : 0;
}
